// GBFS v3.0 feeds (gbfs_feeds.h).
#include "backend/web/gbfs_feeds.h"

#include <algorithm>
#include <cmath>
#include <ctime>

#include "backend/web/registry_reservations.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

json gbfs_localized(const std::string& text, const StandardsOptions& o) {
  return json::array({{{"text", text}, {"language", o.language}}});
}

// Replaces the public id of every vehicle whose trip began since its id was made (see the
// header), and gives one to every listed vehicle without: set-based, so several instances
// building at once agree (the last write wins, one id per vehicle at any time).
constexpr std::string_view kMarkRiding = R"sql(
UPDATE gbfs_public_ids g SET riding_seen = true FROM vehicle_state vs
WHERE vs.vehicle_id = g.vehicle_id AND vs.mode = 'VEHICLE_MODE_RIDING' AND NOT g.riding_seen
)sql";

constexpr std::string_view kRotate = R"sql(
INSERT INTO gbfs_public_ids (vehicle_id, public_id, epoch_us, riding_seen)
SELECT r.vehicle_id, gen_random_uuid()::text, greatest($1::bigint, coalesce(lr.started, 0)), false
FROM registry_vehicles r
JOIN vehicle_state vs ON vs.vehicle_id = r.vehicle_id AND vs.mode <> 'VEHICLE_MODE_RIDING'
LEFT JOIN gbfs_public_ids g ON g.vehicle_id = r.vehicle_id
LEFT JOIN LATERAL (SELECT max(started_at_us) AS started FROM rides
                   WHERE rides.vehicle_id = r.vehicle_id) lr ON true
WHERE r.removed_at_us IS NULL
  AND (g.vehicle_id IS NULL OR g.riding_seen OR coalesce(lr.started, 0) > g.epoch_us)
ON CONFLICT (vehicle_id) DO UPDATE SET public_id = EXCLUDED.public_id,
  epoch_us = EXCLUDED.epoch_us, riding_seen = false
)sql";

// One row per listed vehicle. $1: now (µs); {reserved_at_now}: registry_reservations.h's
// condition at $1.
constexpr std::string_view kStatusSql = R"sql(
SELECT g.public_id, vs.lat_e7, vs.lon_e7, r.vehicle_type_id,
       greatest(vs.received_at_us, st.received_at_us), vs.soc_pct, vs.range_m,
       t.battery_capacity_wh, t.wh_per_km, t.propulsion_type, st.online,
       coalesce(al.active, 0), coalesce(fa.active, 0), e.mwh, e.m,
       EXISTS (SELECT 1 FROM vehicle_reservations rsv WHERE rsv.vehicle_id = r.vehicle_id
               AND {reserved_at_now})
FROM registry_vehicles r
JOIN gbfs_public_ids g ON g.vehicle_id = r.vehicle_id
JOIN vehicle_state vs ON vs.vehicle_id = r.vehicle_id
JOIN registry_vehicle_types t ON t.vehicle_type_id = r.vehicle_type_id
LEFT JOIN status st ON st.vehicle_id = r.vehicle_id
LEFT JOIN LATERAL (
  SELECT count(*) AS active FROM (
    SELECT DISTINCT ON (a.kind, a.lock_kind) a.transition FROM alarms a
    WHERE a.vehicle_id = r.vehicle_id
    ORDER BY a.kind, a.lock_kind, coalesce(a.at_us, a.created_at_us) DESC, a.sequence DESC) x
  WHERE x.transition = 'ALARM_TRANSITION_RAISED') al ON true
LEFT JOIN LATERAL (
  SELECT count(*) AS active FROM (
    SELECT DISTINCT ON (f.node, f.bit) f.kind, f.severity FROM fault_events f
    WHERE f.vehicle_id = r.vehicle_id
    ORDER BY f.node, f.bit, f.created_at_us DESC, f.sequence DESC) y
  WHERE y.kind = 'FAULT_EVENT_KIND_RAISED' AND y.severity = 'FAULT_SEVERITY_CRITICAL') fa ON true
LEFT JOIN LATERAL (
  SELECT sum(energy_mwh) AS mwh, sum(distance_odo_m) AS m FROM (
    SELECT energy_mwh, distance_odo_m FROM rides
    WHERE rides.vehicle_id = r.vehicle_id AND energy_mwh > 0 AND distance_odo_m > 0
    ORDER BY started_at_us DESC NULLS LAST LIMIT 20) z) e ON true
WHERE r.removed_at_us IS NULL AND vs.mode <> 'VEHICLE_MODE_RIDING'
  AND vs.lat_e7 IS NOT NULL AND vs.lon_e7 IS NOT NULL
ORDER BY g.public_id
)sql";

}  // namespace

std::string rfc3339(std::int64_t us) {
  const std::time_t s = static_cast<std::time_t>(us / 1'000'000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

json gbfs_document(const json& data, int ttl_s, std::int64_t now_us) {
  return {{"last_updated", rfc3339(now_us)}, {"ttl", ttl_s}, {"version", "3.0"}, {"data", data}};
}

json gbfs_discovery_data(std::string_view base_url) {
  json feeds = json::array();
  for (const GbfsFeed& f : kGbfsFeeds) {
    feeds.push_back({{"name", f.name},
                     {"url", std::string(base_url) + "/gbfs/" + std::string(f.name) + ".json"}});
  }
  return {{"feeds", feeds}};
}

json gbfs_system_information_data(const StandardsOptions& o) {
  return {{"system_id", o.system_id},
          {"languages", json::array({o.language})},
          {"name", gbfs_localized(o.system_name, o)},
          {"opening_hours", o.opening_hours},
          {"feed_contact_email", o.contact_email},
          {"timezone", o.timezone}};
}

json gbfs_vehicle_types_data(PgConnection& c, const StandardsOptions& o) {
  const PgResult r = c.exec(
      "SELECT vehicle_type_id, name, form_factor, propulsion_type, max_speed_kph, "
      "battery_capacity_wh, wh_per_km FROM registry_vehicle_types ORDER BY vehicle_type_id",
      "gbfs vehicle types");
  json types = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    json t = {{"vehicle_type_id", r.str(i, 0)},
              {"form_factor", r.str(i, 2)},
              {"propulsion_type", r.str(i, 3)}};
    if (!r.str(i, 1).empty()) t["name"] = gbfs_localized(r.str(i, 1), o);
    if (const auto kph = r.int64_or_null(i, 4)) t["max_permitted_speed"] = *kph;
    const auto wh = r.int64_or_null(i, 5);
    if (wh && !r.is_null(i, 6)) {
      t["max_range_meters"] =
          std::round(static_cast<double>(*wh) / std::stod(r.str(i, 6)) * 1000.0);
    } else if (r.str(i, 3) != "human") {
      t["max_range_meters"] = 0;  // validate() refuses such types; a hand-edited row stays valid
    }
    types.push_back(std::move(t));
  }
  return {{"vehicle_types", types}};
}

json gbfs_vehicle_status_data(PgConnection& c, const StandardsOptions& o, std::int64_t now_us) {
  PgTransaction tx(c);
  // PostgreSQL's JIT would spend more compiling these plans (about 2 s for 10,000 vehicles,
  // bench/gbfs-feeds.sh) than running them (0.35 s): off for this build only.
  c.exec("SET LOCAL jit = off", "gbfs jit off");
  c.exec(kMarkRiding, "gbfs ids: riding");
  const PgParam now[] = {std::to_string(now_us)};
  c.query(kRotate, now, "gbfs ids: rotate");
  std::string status_sql(kStatusSql);
  const std::string_view marker = "{reserved_at_now}";
  status_sql.replace(status_sql.find(marker), marker.size(),
                     reservation_in_force_sql("$1::bigint"));
  const PgResult r = c.query(status_sql, now, "gbfs vehicle status");
  tx.commit();
  const std::int64_t offline_us = static_cast<std::int64_t>(o.offline_after_s) * 1'000'000;
  json vehicles = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    json v = {{"vehicle_id", r.str(i, 0)},
              {"lat", static_cast<double>(r.int64(i, 1)) / 1e7},
              {"lon", static_cast<double>(r.int64(i, 2)) / 1e7},
              {"is_reserved", r.boolean(i, 15)},
              {"vehicle_type_id", r.str(i, 3)}};
    const auto last = r.int64_or_null(i, 4);
    if (last) v["last_reported"] = rfc3339(*last);
    const auto soc = r.int64_or_null(i, 5);
    const bool offline = !last || now_us - *last > offline_us ||
                         (!r.is_null(i, 10) && r.str(i, 10) != "ONLINE_STATE_ONLINE");
    const bool low = soc && *soc < o.low_battery_pct;
    v["is_disabled"] = offline || low || r.int64(i, 11) > 0 || r.int64(i, 12) > 0;
    if (r.str(i, 9) != "human") {
      std::optional<double> range;
      const auto cap_wh = r.int64_or_null(i, 7);
      const auto mwh = r.int64_or_null(i, 13);
      const auto m = r.int64_or_null(i, 14);
      if (soc && cap_wh && mwh && m && *m >= 1000 && *mwh > 0) {
        const double wh_per_km = static_cast<double>(*mwh) / static_cast<double>(*m);  // mWh/m
        range =
            static_cast<double>(*soc) / 100.0 * static_cast<double>(*cap_wh) / wh_per_km * 1000.0;
      } else if (const auto rm = r.int64_or_null(i, 6)) {
        range = static_cast<double>(*rm);
      } else if (soc && cap_wh && !r.is_null(i, 8)) {
        range = static_cast<double>(*soc) / 100.0 * static_cast<double>(*cap_wh) /
                std::stod(r.str(i, 8)) * 1000.0;
      }
      // GBFS requires it of motorised vehicles: 0 when nothing tells the range.
      v["current_range_meters"] = std::round(std::max(0.0, range.value_or(0.0)));
    }
    if (soc) v["current_fuel_percent"] = std::clamp(static_cast<double>(*soc) / 100.0, 0.0, 1.0);
    vehicles.push_back(std::move(v));
  }
  return {{"vehicles", vehicles}};
}

}  // namespace fleetgw::web
