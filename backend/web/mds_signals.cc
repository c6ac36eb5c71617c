// The rows behind MDS (mds_signals.h).
#include "backend/web/mds_signals.h"

#include "backend/web/registry_reservations.h"
#include "backend/web/registry_store.h"

namespace fleetgw::web {
namespace {

constexpr std::int64_t kDayUs = 86'400'000'000;

// Alarm kinds that take a bike out of service while active (theft or tampering).
constexpr std::string_view kTheftKinds =
    "{ALARM_KIND_UNAUTHORISED_MOVEMENT,ALARM_KIND_LOCK_FORCED,ALARM_KIND_LOCK_TAMPER,"
    "ALARM_KIND_BATTERY_REMOVED}";
constexpr std::string_view kOutsideKind = "ALARM_KIND_OUTSIDE_OPERATING_AREA";

MdsPlace place_of(const PgResult& r, int row, int lat_col, int lon_col, int soc_col) {
  MdsPlace p;
  if (const auto v = r.int64_or_null(row, lat_col)) p.lat = static_cast<double>(*v) / 1e7;
  if (const auto v = r.int64_or_null(row, lon_col)) p.lon = static_cast<double>(*v) / 1e7;
  if (soc_col >= 0) {
    if (const auto v = r.int64_or_null(row, soc_col)) p.soc_pct = static_cast<int>(*v);
  }
  return p;
}

}  // namespace

std::string pg_text_array(const std::vector<std::string>& items) {
  std::string out = "{";
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += ',';
    out += '"';
    for (const char ch : items[i]) {
      if (ch == '"' || ch == '\\') out += '\\';
      out += ch;
    }
    out += '"';
  }
  return out + "}";
}

std::string mds_trip_id(const std::string& vehicle_id, const std::string& ride_id) {
  // Length-prefixed so that no two (vehicle, ride) pairs share a name.
  return name_uuid("trip:" + std::to_string(vehicle_id.size()) + ":" + vehicle_id + ride_id);
}

std::vector<MdsVehicleRow> mds_registry_page(PgConnection& c,
                                             const std::optional<std::string>& device_id,
                                             std::int64_t offset, int limit, bool* more) {
  const PgParam p[] = {device_id && is_uuid(*device_id) ? PgParam(*device_id) : std::nullopt,
                       device_id ? PgParam("1") : std::nullopt, std::to_string(offset),
                       std::to_string(limit + 1)};
  const PgResult r = c.query(
      "SELECT v.vehicle_id, v.device_id::text, v.provider_id::text, v.provider_name, "
      "t.form_factor, t.propulsion_type, t.max_speed_kph, t.battery_capacity_mah, "
      "v.removed_at_us FROM registry_vehicles v JOIN registry_vehicle_types t USING "
      "(vehicle_type_id) WHERE $2::text IS NULL OR v.device_id = $1::uuid "
      "ORDER BY v.vehicle_id OFFSET $3 LIMIT $4",
      p, "mds registry page");
  std::vector<MdsVehicleRow> out;
  for (int i = 0; i < r.rows() && i < limit; ++i) {
    out.push_back({r.str(i, 0), r.str(i, 1), r.str(i, 2), r.str(i, 3), r.str(i, 4), r.str(i, 5),
                   r.int64_or_null(i, 6), r.int64_or_null(i, 7), r.int64_or_null(i, 8)});
  }
  *more = r.rows() > limit;
  return out;
}

std::map<std::string, MdsTimeline> mds_timelines(PgConnection& c, const StandardsOptions& o,
                                                 const std::vector<std::string>& ids,
                                                 std::int64_t from_us, std::int64_t to_us) {
  std::map<std::string, MdsTimeline> out;
  for (const std::string& id : ids) out[id];
  if (ids.empty()) return out;
  const std::string vs = pg_text_array(ids);
  const std::string from = std::to_string(from_us);
  const std::string to = std::to_string(to_us);

  // The latest state and status: position, SOC, last report, riding now.
  {
    const PgParam p[] = {vs};
    const PgResult r = c.query(
        "SELECT v.id, s.lat_e7, s.lon_e7, s.soc_pct, greatest(s.received_at_us, "
        "st.received_at_us), s.mode = 'VEHICLE_MODE_RIDING', s.updated_at_us, "
        "s.heading_ddeg, s.horizontal_error_dm "
        "FROM unnest($1::text[]) AS v(id) LEFT JOIN vehicle_state s ON "
        "s.vehicle_id = v.id LEFT JOIN status st ON st.vehicle_id = v.id",
        p, "mds latest state");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      t.latest = place_of(r, i, 1, 2, 3);
      t.last_report_us = r.int64_or_null(i, 4);
      t.riding_now = r.boolean(i, 5);
      t.state_updated_us = r.int64_or_null(i, 6).value_or(0);
      if (const auto v = r.int64_or_null(i, 7)) t.heading_deg = static_cast<double>(*v) / 10.0;
      if (const auto v = r.int64_or_null(i, 8))
        t.horizontal_error_m = static_cast<double>(*v) / 10.0;
      // Silence: no report for offline_after_s (a status_history row below may say more).
      if (t.last_report_us) {
        const std::int64_t silent = *t.last_report_us + std::int64_t{o.offline_after_s} * 1'000'000;
        if (silent < from_us) {
          t.start.offline = true;
          t.start.offline_since_us = silent;
        } else if (silent < to_us) {
          t.signals.push_back({silent, MdsSignalKind::CommsLost, "", {}});
        }
      }
    }
  }

  // Connection changes (the ingest's status_history, migration 4): the latest before the
  // window and those within it; a last will counts from its arrival.
  {
    const PgParam p[] = {vs, from, to};
    const PgResult r = c.query(
        "(SELECT DISTINCT ON (vehicle_id) vehicle_id, event_at_us, online FROM status_history "
        "WHERE vehicle_id = ANY($1::text[]) AND event_at_us < $2::bigint ORDER BY vehicle_id, "
        "event_at_us DESC, id DESC) UNION ALL (SELECT vehicle_id, event_at_us, online FROM "
        "status_history WHERE vehicle_id = ANY($1::text[]) AND event_at_us >= $2::bigint AND "
        "event_at_us < $3::bigint) ORDER BY 1, 2",
        p, "mds connection changes");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      const std::int64_t at = r.int64(i, 1);
      const bool online = r.text(i, 2) == "ONLINE_STATE_ONLINE";
      if (at < from_us) {
        if (!online && !t.start.offline) {
          t.start.offline = true;
          t.start.offline_since_us = at;
        }
        continue;
      }
      t.signals.push_back(
          {at, online ? MdsSignalKind::CommsRestored : MdsSignalKind::CommsLost, "", {}});
    }
  }

  // Rides: open at the window's start, starting or ending within it.
  {
    const PgParam p[] = {vs, from, to};
    const PgResult r = c.query(
        "SELECT vehicle_id, ride_id, started_at_us, ended_at_us, start_lat_e7, start_lon_e7, "
        "soc_start_pct, end_lat_e7, end_lon_e7, soc_end_pct FROM rides WHERE vehicle_id = "
        "ANY($1::text[]) AND started_at_us < $3::bigint AND coalesce(ended_at_us, started_at_us) "
        ">= $2::bigint ORDER BY vehicle_id, started_at_us",
        p, "mds rides");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      const std::string trip = mds_trip_id(r.str(i, 0), r.str(i, 1));
      const std::int64_t start = r.int64(i, 2);
      const auto end = r.int64_or_null(i, 3);
      if (start < from_us) {
        if (end && *end >= from_us) {
          t.start.on_trip = true;
          t.start.trip_id = trip;
        }
      } else {
        t.signals.push_back({start, MdsSignalKind::TripStart, trip, place_of(r, i, 4, 5, 6)});
      }
      if (end && *end >= from_us && *end < to_us) {
        t.signals.push_back({*end, MdsSignalKind::TripEnd, trip, place_of(r, i, 7, 8, 9)});
      }
    }
  }

  // Alarms: each kind's latest transition before the window, and the window's transitions.
  {
    const PgParam p[] = {vs, from, to, std::string(kTheftKinds), std::string(kOutsideKind)};
    const PgResult r = c.query(
        "(SELECT DISTINCT ON (vehicle_id, kind, lock_kind) vehicle_id, kind, transition, "
        "coalesce(at_us, created_at_us) AS t, sequence FROM alarms WHERE vehicle_id = "
        "ANY($1::text[]) AND (kind = ANY($4::text[]) OR kind = $5) AND coalesce(at_us, "
        "created_at_us) < $2::bigint ORDER BY vehicle_id, kind, lock_kind, t DESC, sequence DESC) "
        "UNION ALL (SELECT vehicle_id, kind, transition, coalesce(at_us, created_at_us) AS t, "
        "sequence FROM alarms WHERE vehicle_id = ANY($1::text[]) AND (kind = ANY($4::text[]) OR "
        "kind = $5) AND coalesce(at_us, created_at_us) >= $2::bigint AND coalesce(at_us, "
        "created_at_us) < $3::bigint) ORDER BY 1, 4, 5",
        p, "mds alarms");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      const bool outside = r.text(i, 1) == kOutsideKind;
      const bool raised = r.text(i, 2) == "ALARM_TRANSITION_RAISED";
      const std::int64_t at = r.int64(i, 3);
      if (at < from_us) {
        (outside ? t.start.outside : t.start.theft) = raised;
        continue;
      }
      const MdsSignalKind k =
          outside ? (raised ? MdsSignalKind::LeaveArea : MdsSignalKind::EnterArea)
                  : (raised ? MdsSignalKind::TheftRaised : MdsSignalKind::TheftCleared);
      t.signals.push_back({at, k, "", {}});
    }
  }

  // Battery: the last SOC of the day before the window, and its crossings within it.
  {
    const PgParam pb[] = {vs, from, std::to_string(from_us - kDayUs)};
    const PgParam p[] = {vs, from, to, std::to_string(o.low_battery_pct),
                         std::to_string(o.charged_pct)};
    const PgResult before = c.query(
        "SELECT DISTINCT ON (vehicle_id) vehicle_id, soc_pct FROM telemetry_samples WHERE "
        "vehicle_id = ANY($1::text[]) AND sampled_at_us >= $3::bigint AND sampled_at_us < "
        "$2::bigint AND soc_pct IS NOT NULL ORDER BY vehicle_id, sampled_at_us DESC",
        pb, "mds soc before");
    for (int i = 0; i < before.rows(); ++i) {
      out[before.str(i, 0)].start.low_battery = before.int64(i, 1) < o.low_battery_pct;
    }
    const PgResult r = c.query(
        "SELECT vehicle_id, sampled_at_us, soc_pct, lat_e7, lon_e7 FROM (SELECT vehicle_id, "
        "sampled_at_us, soc_pct, lat_e7, lon_e7, lag(soc_pct) OVER (PARTITION BY vehicle_id "
        "ORDER BY sampled_at_us) AS prev FROM telemetry_samples WHERE vehicle_id = "
        "ANY($1::text[]) AND sampled_at_us >= $2::bigint AND sampled_at_us < $3::bigint AND "
        "soc_pct IS NOT NULL) x WHERE (soc_pct < $4::int AND (prev IS NULL OR prev >= $4::int)) "
        "OR (soc_pct >= $5::int AND (prev IS NULL OR prev < $5::int)) ORDER BY vehicle_id, "
        "sampled_at_us",
        p, "mds soc crossings");
    for (int i = 0; i < r.rows(); ++i) {
      const bool low = r.int64(i, 2) < o.low_battery_pct;
      out[r.str(i, 0)].signals.push_back(
          {r.int64(i, 1), low ? MdsSignalKind::BatteryLow : MdsSignalKind::BatteryOk, "",
           place_of(r, i, 3, 4, 2)});
    }
  }

  // Reservations (registry_reservations.h): in force at the window's start, or starting or
  // ending within it. An end after a trip took the vehicle changes nothing (the machine's
  // trip start ended the reservation).
  {
    const PgParam p[] = {vs, from, to};
    const PgResult r =
        c.query("SELECT rsv.vehicle_id, rsv.started_at_us, rsv.ends_at_us, " +
                    reservation_in_force_sql("$2::bigint") +
                    " FROM vehicle_reservations rsv WHERE rsv.vehicle_id = ANY($1::text[]) AND "
                    "rsv.started_at_us < $3::bigint AND rsv.ends_at_us >= $2::bigint ORDER BY 1, 2",
                p, "mds reservations");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      const std::int64_t start = r.int64(i, 1);
      const std::int64_t end = r.int64(i, 2);
      if (start < from_us) {
        if (r.boolean(i, 3)) t.start.reserved = true;
      } else {
        t.signals.push_back({start, MdsSignalKind::ReservationStart, "", {}});
      }
      if (end >= from_us && end < to_us) {
        t.signals.push_back({end, MdsSignalKind::ReservationEnd, "", {}});
      }
    }
  }

  // Removal from the fleet.
  {
    const PgParam p[] = {vs};
    const PgResult r = c.query(
        "SELECT vehicle_id, removed_at_us FROM registry_vehicles WHERE vehicle_id = "
        "ANY($1::text[]) AND removed_at_us IS NOT NULL",
        p, "mds removals");
    for (int i = 0; i < r.rows(); ++i) {
      MdsTimeline& t = out[r.str(i, 0)];
      const std::int64_t at = r.int64(i, 1);
      if (at < from_us) {
        t.start.removed = true;
      } else if (at < to_us) {
        t.signals.push_back({at, MdsSignalKind::Removed, "", {}});
      }
    }
  }
  return out;
}

}  // namespace fleetgw::web
