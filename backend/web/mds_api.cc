// MDS 2.0 Provider API data (mds_api.h).
#include "backend/web/mds_api.h"

#include "backend/web/mds_signals.h"
#include "backend/web/registry_store.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr std::int64_t kHourUs = 3'600'000'000;

std::int64_t to_ms(std::int64_t us) {
  return us / 1000;
}

json mds_gps(const MdsPlace& p) {
  return {{"lat", *p.lat}, {"lng", *p.lon}};
}

// MDS GPS `heading` (degrees) and `horizontal_accuracy` (metres) from a sample's fix (ingest
// migration 8: heading_ddeg, horizontal_error_dm at columns col, col + 1), when it had them.
void add_fix_quality(json& loc, const PgResult& r, int row, int col) {
  if (const auto dd = r.int64_or_null(row, col)) loc["heading"] = static_cast<double>(*dd) / 10.0;
  if (const auto dm = r.int64_or_null(row, col + 1)) {
    loc["horizontal_accuracy"] = static_cast<double>(*dm) / 10.0;
  }
}

json propulsion_types(const std::string& propulsion) {
  // A pedal-assist bike also rides as a plain bicycle (MDS: ["human", "electric_assist"]).
  if (propulsion == "electric_assist") return json::array({"human", "electric_assist"});
  return json::array({propulsion});
}

json event_json(const MdsVehicleRow& v, const MdsEvent& e, const std::string& vehicle_id) {
  json j = {{"device_id", v.device_id},
            {"provider_id", v.provider_id},
            {"event_id", name_uuid("event:" + std::to_string(vehicle_id.size()) + ":" + vehicle_id +
                                   std::to_string(e.at_us) + e.types.front())},
            {"vehicle_state", e.state},
            {"event_types", e.types},
            {"timestamp", to_ms(e.at_us)},
            {"location", mds_gps(e.place)}};
  if (e.place.soc_pct) j["battery_percent"] = *e.place.soc_pct;
  if (!e.trip_id.empty()) j["trip_ids"] = json::array({e.trip_id});
  return j;
}

// The events of one vehicle's timeline, each given a location (the row's, else the last one
// before, else the vehicle's latest); ones with none at all are dropped.
std::vector<MdsEvent> located_events(const MdsTimeline& t, std::int64_t until_us,
                                     std::int64_t missing_after_us) {
  std::vector<MdsEvent> events = derive_events(t.start, t.signals, missing_after_us, until_us);
  MdsPlace last;
  std::vector<MdsEvent> out;
  for (MdsEvent& e : events) {
    if (e.place.lat && e.place.lon) {
      last = e.place;
    } else if (last.lat) {
      e.place.lat = last.lat;
      e.place.lon = last.lon;
    } else if (t.latest.lat && t.latest.lon) {
      e.place.lat = t.latest.lat;
      e.place.lon = t.latest.lon;
    } else {
      continue;
    }
    if (!e.place.soc_pct) e.place.soc_pct = t.latest.soc_pct;
    out.push_back(std::move(e));
  }
  return out;
}

std::int64_t missing_after(const StandardsOptions&) {
  // Out of contact for a day: the last position can no longer be trusted.
  return 24 * kHourUs;
}

}  // namespace

json mds_vehicles(PgConnection& c, const StandardsOptions&,
                  const std::optional<std::string>& device_id, MdsPageRequest page, bool* more) {
  json out = json::array();
  for (const MdsVehicleRow& v : mds_registry_page(c, device_id, page.offset, page.limit, more)) {
    json j = {{"device_id", v.device_id},
              {"provider_id", v.provider_id},
              {"vehicle_id", v.vehicle_id},
              {"vehicle_type", v.vehicle_type},
              {"propulsion_types", propulsion_types(v.propulsion)},
              // Required by MDS 2.0's Vehicle (array or object): fleetgw records none.
              {"accessibility_options", json::array()}};
    if (v.battery_mah) j["battery_capacity"] = *v.battery_mah;
    if (v.max_speed_kph) j["maximum_speed"] = *v.max_speed_kph;
    out.push_back(std::move(j));
  }
  return out;
}

json mds_vehicles_status(PgConnection& c, const StandardsOptions& o,
                         const std::optional<std::string>& device_id, std::int64_t now_us,
                         MdsPageRequest page, bool* more) {
  const std::vector<MdsVehicleRow> rows =
      mds_registry_page(c, device_id, page.offset, page.limit, more);
  std::vector<std::string> ids;
  for (const MdsVehicleRow& v : rows) ids.push_back(v.vehicle_id);
  const std::int64_t from = now_us - kHourUs;
  std::map<std::string, MdsTimeline> timelines = mds_timelines(c, o, ids, from, now_us + 1);

  // The latest telemetry with a position of the last day, one row per vehicle.
  std::map<std::string, json> telemetry;
  {
    const PgParam p[] = {pg_text_array(ids), std::to_string(now_us - 24 * kHourUs)};
    const PgResult r = c.query(
        "SELECT DISTINCT ON (vehicle_id) vehicle_id, store_id, sequence, sampled_at_us, "
        "lat_e7, lon_e7, speed_dkmh, soc_pct, heading_ddeg, horizontal_error_dm FROM "
        "telemetry_samples WHERE vehicle_id = "
        "ANY($1::text[]) AND sampled_at_us >= $2::bigint AND lat_e7 IS NOT NULL AND lon_e7 IS "
        "NOT NULL ORDER BY vehicle_id, sampled_at_us DESC",
        p, "mds last telemetry");
    for (int i = 0; i < r.rows(); ++i) {
      json loc = {{"lat", static_cast<double>(r.int64(i, 4)) / 1e7},
                  {"lng", static_cast<double>(r.int64(i, 5)) / 1e7}};
      if (const auto dkmh = r.int64_or_null(i, 6)) loc["speed"] = static_cast<double>(*dkmh) / 36.0;
      add_fix_quality(loc, r, i, 8);
      json t = {{"telemetry_id",
                 name_uuid("telemetry:" + r.str(i, 0) + "/" + r.str(i, 1) + "/" + r.str(i, 2))},
                {"timestamp", to_ms(r.int64(i, 3))},
                {"trip_ids", nullptr},
                {"journey_id", nullptr},
                {"location", loc}};
      if (const auto soc = r.int64_or_null(i, 7)) t["battery_percent"] = *soc;
      telemetry[r.str(i, 0)] = std::move(t);
    }
  }

  json out = json::array();
  for (const MdsVehicleRow& v : rows) {
    MdsTimeline& t = timelines[v.vehicle_id];
    // A ride in progress has no ride record yet (the gateway sends it at the end): its start is
    // the riding state's, with a provisional trip id until the record names the trip.
    if (t.riding_now) {
      bool open = t.start.on_trip;
      for (const MdsSignal& s : t.signals) {
        if (s.kind == MdsSignalKind::TripStart) open = true;
        if (s.kind == MdsSignalKind::TripEnd) open = false;
      }
      if (!open) {
        t.signals.push_back(
            {std::max(t.state_updated_us, from), MdsSignalKind::TripStart,
             name_uuid("live-trip:" + v.vehicle_id + ":" + std::to_string(t.state_updated_us)),
             t.latest});
      }
    }
    std::vector<MdsEvent> events = located_events(t, now_us, missing_after(o));
    MdsEvent last;
    if (!events.empty()) {
      last = events.back();
    } else {
      // Nothing changed within the hour: the state the conditions give, as of the last report.
      MdsMachine m(t.start, missing_after(o));
      if (!t.latest.lat || !t.latest.lon) continue;  // never located: no MDS status possible
      last = {
          t.last_report_us.value_or(now_us), m.state(), {"unspecified"}, t.start.trip_id, t.latest};
      if (m.state() != "on_trip" && m.state() != "elsewhere") last.trip_id.clear();
    }
    json status = {{"device_id", v.device_id},
                   {"provider_id", v.provider_id},
                   {"last_event", event_json(v, last, v.vehicle_id)}};
    if (auto it = telemetry.find(v.vehicle_id); it != telemetry.end()) {
      json tel = it->second;
      tel["device_id"] = v.device_id;
      tel["provider_id"] = v.provider_id;
      if (last.state == "on_trip" && !last.trip_id.empty()) tel["trip_ids"] = {last.trip_id};
      status["last_telemetry"] = std::move(tel);
    } else {
      status["last_telemetry"] = {{"device_id", v.device_id},
                                  {"provider_id", v.provider_id},
                                  {"telemetry_id", name_uuid("state:" + v.vehicle_id + ":" +
                                                             std::to_string(t.state_updated_us))},
                                  {"timestamp", to_ms(t.state_updated_us)},
                                  {"trip_ids", nullptr},
                                  {"journey_id", nullptr},
                                  {"location", mds_gps(last.place)}};
      // The state's fix carries what telemetry samples do not store: heading and accuracy.
      json& loc = status["last_telemetry"]["location"];
      if (t.heading_deg) loc["heading"] = *t.heading_deg;
      if (t.horizontal_error_m) loc["horizontal_accuracy"] = *t.horizontal_error_m;
    }
    out.push_back(std::move(status));
  }
  return out;
}

json mds_trips(PgConnection& c, const StandardsOptions&, std::int64_t from_us, std::int64_t to_us,
               MdsPageRequest page, bool* more) {
  const PgParam p[] = {std::to_string(from_us), std::to_string(to_us), std::to_string(page.offset),
                       std::to_string(page.limit + 1)};
  // The ride's own start/end positions, else its first/last telemetry position.
  const PgResult r = c.query(
      "SELECT r.vehicle_id, r.ride_id, v.device_id::text, v.provider_id::text, r.started_at_us, "
      "r.ended_at_us, coalesce(r.distance_odo_m, r.distance_gnss_m, r.distance_integrated_m, 0), "
      "coalesce(r.start_lat_e7, f.lat_e7), coalesce(r.start_lon_e7, f.lon_e7), "
      "coalesce(r.end_lat_e7, l.lat_e7), coalesce(r.end_lon_e7, l.lon_e7), r.committed_at_us "
      "FROM rides r JOIN registry_vehicles v ON v.vehicle_id = r.vehicle_id "
      "LEFT JOIN LATERAL (SELECT lat_e7, lon_e7 FROM telemetry_samples t WHERE t.vehicle_id = "
      "r.vehicle_id AND t.sampled_at_us BETWEEN r.started_at_us AND r.ended_at_us AND t.lat_e7 "
      "IS NOT NULL ORDER BY t.sampled_at_us LIMIT 1) f ON r.start_lat_e7 IS NULL "
      "LEFT JOIN LATERAL (SELECT lat_e7, lon_e7 FROM telemetry_samples t WHERE t.vehicle_id = "
      "r.vehicle_id AND t.sampled_at_us BETWEEN r.started_at_us AND r.ended_at_us AND t.lat_e7 "
      "IS NOT NULL ORDER BY t.sampled_at_us DESC LIMIT 1) l ON r.end_lat_e7 IS NULL "
      "WHERE r.ended_at_us >= $1::bigint AND r.ended_at_us < $2::bigint AND r.started_at_us IS "
      "NOT NULL ORDER BY r.ended_at_us, r.vehicle_id, r.store_id, r.sequence OFFSET $3 LIMIT $4",
      p, "mds trips");
  json out = json::array();
  for (int i = 0; i < r.rows() && i < page.limit; ++i) {
    if (r.is_null(i, 7) || r.is_null(i, 8) || r.is_null(i, 9) || r.is_null(i, 10)) continue;
    const std::int64_t start = r.int64(i, 4);
    const std::int64_t end = r.int64(i, 5);
    out.push_back({{"provider_id", r.str(i, 3)},
                   {"device_id", r.str(i, 2)},
                   {"trip_id", mds_trip_id(r.str(i, 0), r.str(i, 1))},
                   {"trip_type", "rider"},
                   {"start_time", to_ms(start)},
                   {"end_time", to_ms(end)},
                   {"start_location", {{"lat", r.int64(i, 7) / 1e7}, {"lng", r.int64(i, 8) / 1e7}}},
                   {"end_location", {{"lat", r.int64(i, 9) / 1e7}, {"lng", r.int64(i, 10) / 1e7}}},
                   {"duration", (end - start) / 1'000'000},
                   {"distance", r.int64(i, 6)},
                   {"publication_time", to_ms(r.int64(i, 11))}});
  }
  *more = r.rows() > page.limit;
  return out;
}

json mds_telemetry(PgConnection& c, const StandardsOptions&, std::int64_t from_us,
                   std::int64_t to_us, MdsPageRequest page, bool* more) {
  const PgParam p[] = {std::to_string(from_us), std::to_string(to_us), std::to_string(page.offset),
                       std::to_string(page.limit + 1)};
  const PgResult r = c.query(
      "SELECT t.vehicle_id, t.store_id, t.sequence, v.device_id::text, v.provider_id::text, "
      "t.sampled_at_us, t.lat_e7, t.lon_e7, t.speed_dkmh, t.soc_pct, ride.ride_id, "
      "t.heading_ddeg, t.horizontal_error_dm FROM telemetry_samples t JOIN registry_vehicles v ON "
      "v.vehicle_id = t.vehicle_id "
      "LEFT JOIN LATERAL (SELECT ride_id FROM rides WHERE rides.vehicle_id = t.vehicle_id AND "
      "rides.started_at_us <= t.sampled_at_us AND rides.ended_at_us >= t.sampled_at_us "
      "LIMIT 1) ride ON true WHERE t.sampled_at_us >= $1::bigint AND t.sampled_at_us < "
      "$2::bigint AND t.lat_e7 IS NOT NULL AND t.lon_e7 IS NOT NULL "
      "ORDER BY t.sampled_at_us, t.vehicle_id, t.store_id, t.sequence OFFSET $3 LIMIT $4",
      p, "mds telemetry");
  json out = json::array();
  for (int i = 0; i < r.rows() && i < page.limit; ++i) {
    json loc = {{"lat", r.int64(i, 6) / 1e7}, {"lng", r.int64(i, 7) / 1e7}};
    if (const auto dkmh = r.int64_or_null(i, 8)) loc["speed"] = static_cast<double>(*dkmh) / 36.0;
    add_fix_quality(loc, r, i, 11);
    json t = {
        {"device_id", r.str(i, 3)},
        {"provider_id", r.str(i, 4)},
        {"telemetry_id",
         name_uuid("telemetry:" + r.str(i, 0) + "/" + r.str(i, 1) + "/" + r.str(i, 2))},
        {"timestamp", to_ms(r.int64(i, 5))},
        {"trip_ids",
         r.is_null(i, 10) ? json(nullptr) : json::array({mds_trip_id(r.str(i, 0), r.str(i, 10))})},
        {"journey_id", nullptr},
        {"location", loc}};
    if (const auto soc = r.int64_or_null(i, 9)) t["battery_percent"] = *soc;
    out.push_back(std::move(t));
  }
  *more = r.rows() > page.limit;
  return out;
}

json mds_events(PgConnection& c, const StandardsOptions& o, std::int64_t from_us,
                std::int64_t to_us, MdsPageRequest page, bool* more) {
  const std::vector<MdsVehicleRow> rows =
      mds_registry_page(c, std::nullopt, page.offset, page.limit, more);
  std::vector<std::string> ids;
  for (const MdsVehicleRow& v : rows) ids.push_back(v.vehicle_id);
  const std::map<std::string, MdsTimeline> timelines = mds_timelines(c, o, ids, from_us, to_us);
  json out = json::array();
  for (const MdsVehicleRow& v : rows) {
    const auto it = timelines.find(v.vehicle_id);
    if (it == timelines.end()) continue;
    for (const MdsEvent& e : located_events(it->second, to_us - 1, missing_after(o))) {
      if (e.at_us >= from_us && e.at_us < to_us) out.push_back(event_json(v, e, v.vehicle_id));
    }
  }
  return out;
}

}  // namespace fleetgw::web
