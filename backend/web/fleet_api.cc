// Reads behind the operator API (fleet_api.h).
#include "backend/web/fleet_api.h"

#include <charconv>
#include <vector>

#include "backend/web/ride_api.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr int kLowBatteryPct = 20;

// One row per vehicle, the latest of everything the console shows about it. $1 NULL: the whole
// fleet; else that vehicle only. Each LATERAL part is an index lookup on the ingest's primary
// keys (they begin with vehicle_id) or on telemetry_by_time.
constexpr std::string_view kFleetSql = R"sql(
SELECT v.vehicle_id, vs.lat_e7, vs.lon_e7, vs.mode, vs.online, st.online, st.connection,
       vs.soc_pct, vs.range_m, t.speed_dkmh, t.sampled_at_us,
       greatest(vs.received_at_us, st.received_at_us), vs.updated_at_us,
       coalesce(lk.locks, '[]'), coalesce(al.kinds, '[]'), coalesce(al.active, 0),
       coalesce(al.unacked, 0)
FROM (SELECT vehicle_id FROM vehicle_state WHERE $1::text IS NULL OR vehicle_id = $1
      UNION SELECT vehicle_id FROM status WHERE $1::text IS NULL OR vehicle_id = $1) v
LEFT JOIN vehicle_state vs ON vs.vehicle_id = v.vehicle_id
LEFT JOIN status st ON st.vehicle_id = v.vehicle_id
LEFT JOIN LATERAL (
  SELECT ts.speed_dkmh, ts.sampled_at_us FROM telemetry_samples ts
  WHERE ts.vehicle_id = v.vehicle_id ORDER BY ts.sampled_at_us DESC LIMIT 1) t ON true
LEFT JOIN LATERAL (
  SELECT json_agg(json_build_object('kind', l.lock_kind, 'state', l.state, 'name', l.state_name)
                  ORDER BY l.lock_kind) AS locks
  FROM (SELECT DISTINCT ON (le.node, le.lock_kind) le.lock_kind, le.state, le.state_name
        FROM lock_events le WHERE le.vehicle_id = v.vehicle_id
        ORDER BY le.node, le.lock_kind, coalesce(le.at_us, le.created_at_us) DESC,
                 le.sequence DESC) l) lk ON true
LEFT JOIN LATERAL (
  SELECT json_agg(last.kind ORDER BY last.kind) AS kinds, count(*) AS active,
         count(*) FILTER (WHERE k.acked_by IS NULL) AS unacked
  FROM (SELECT DISTINCT ON (a.kind, a.lock_kind) a.kind, a.transition, a.store_id, a.sequence
        FROM alarms a WHERE a.vehicle_id = v.vehicle_id
        ORDER BY a.kind, a.lock_kind, coalesce(a.at_us, a.created_at_us) DESC,
                 a.sequence DESC) last
  LEFT JOIN console_alarm_acks k ON k.vehicle_id = v.vehicle_id
       AND k.store_id = last.store_id AND k.sequence = last.sequence
  WHERE last.transition = 'ALARM_TRANSITION_RAISED' AND NOT EXISTS (
    SELECT 1 FROM console_alarm_resolutions res WHERE res.vehicle_id = v.vehicle_id
      AND res.store_id = last.store_id AND res.sequence = last.sequence)) al ON true
ORDER BY v.vehicle_id
)sql";

// The alarm rows with whether each is still the active one of its (vehicle, kind, lock kind).
constexpr std::string_view kAlarmColumns = R"sql(
  a.vehicle_id, a.store_id, a.sequence, a.kind, a.transition, a.at_us, a.created_at_us,
  a.committed_at_us, a.speed_dkmh, a.soc_pct, a.lock_kind, a.detail, k.acked_by, k.acked_at_us,
  a.transition = 'ALARM_TRANSITION_RAISED' AND res.resolved_by IS NULL AND NOT EXISTS (
    SELECT 1 FROM alarms b WHERE b.vehicle_id = a.vehicle_id AND b.kind = a.kind
      AND b.lock_kind = a.lock_kind
      AND (coalesce(b.at_us, b.created_at_us), b.sequence)
          > (coalesce(a.at_us, a.created_at_us), a.sequence))
  , res.resolved_by, res.resolved_at_us, res.note
FROM alarms a LEFT JOIN console_alarm_acks k ON k.vehicle_id = a.vehicle_id
  AND k.store_id = a.store_id AND k.sequence = a.sequence
LEFT JOIN console_alarm_resolutions res ON res.vehicle_id = a.vehicle_id
  AND res.store_id = a.store_id AND res.sequence = a.sequence
)sql";

json opt_int(const PgResult& r, int row, int col) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(*v) : json(nullptr);
}

json opt_text(const PgResult& r, int row, int col) {
  return r.is_null(row, col) ? json(nullptr) : json(r.str(row, col));
}

json degrees(const PgResult& r, int row, int col) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(static_cast<double>(*v) / 1e7) : json(nullptr);
}

// PostgreSQL's own JSON output (json_agg): parsed so it is re-serialised by us, escaped alike.
json pg_json(const PgResult& r, int row, int col) {
  json j = json::parse(r.str(row, col), nullptr, /*allow_exceptions=*/false);
  return j.is_discarded() ? json(nullptr) : j;
}

std::string mode_name(std::string_view m) {
  if (m == "VEHICLE_MODE_PARKED") return "parked";
  if (m == "VEHICLE_MODE_RIDING") return "riding";
  return "unknown";
}

json fleet_row(const PgResult& r, int i) {
  json v;
  v["id"] = r.str(i, 0);
  v["lat"] = degrees(r, i, 1);
  v["lon"] = degrees(r, i, 2);
  v["mode"] = r.is_null(i, 3) ? "unknown" : mode_name(r.str(i, 3));
  // The retained status is the authority on the connection (its last will says offline);
  // a vehicle that never published one falls back to its state's flag.
  const bool online = r.is_null(i, 5) ? r.boolean(i, 4) : r.str(i, 5) == "ONLINE_STATE_ONLINE";
  v["online"] = online;
  v["connection"] = opt_text(r, i, 6);
  v["soc_pct"] = opt_int(r, i, 7);
  v["range_m"] = opt_int(r, i, 8);
  const auto dkmh = r.int64_or_null(i, 9);
  v["speed_kmh"] = dkmh ? json(static_cast<double>(*dkmh) / 10.0) : json(nullptr);
  v["speed_at_us"] = opt_int(r, i, 10);
  v["last_seen_us"] = opt_int(r, i, 11);
  v["updated_at_us"] = opt_int(r, i, 12);
  v["locks"] = pg_json(r, i, 13);
  v["alarms"] = {{"kinds", pg_json(r, i, 14)},
                 {"active", r.int64_or_null(i, 15).value_or(0)},
                 {"unacked", r.int64_or_null(i, 16).value_or(0)}};
  const auto soc = r.int64_or_null(i, 7);
  std::string state = "parked";
  if (r.int64_or_null(i, 15).value_or(0) > 0) {
    state = "alarm";
  } else if (!online) {
    state = "offline";
  } else if (soc && *soc < kLowBatteryPct) {
    state = "low_battery";
  } else if (v["mode"] == "riding") {
    state = "riding";
  }
  v["state"] = state;
  return v;
}

// The same vehicle as fleet_row(), as one array in the order of kCompactFleetFields: what the map
// and the list show, about a quarter of the bytes (no field names, no mode/online/connection/
// range, locks as [kind, name] pairs). Built from the row directly: a quarter of the work too.
json compact_row(const PgResult& r, int i) {
  const bool online = r.is_null(i, 5) ? r.boolean(i, 4) : r.str(i, 5) == "ONLINE_STATE_ONLINE";
  const auto soc = r.int64_or_null(i, 7);
  const std::int64_t active = r.int64_or_null(i, 15).value_or(0);
  const char* state = "parked";
  if (active > 0) {
    state = "alarm";
  } else if (!online) {
    state = "offline";
  } else if (soc && *soc < kLowBatteryPct) {
    state = "low_battery";
  } else if (!r.is_null(i, 3) && r.str(i, 3) == "VEHICLE_MODE_RIDING") {
    state = "riding";
  }
  json locks = json::array();
  if (r.str(i, 13) != "[]") {
    for (const json& l : pg_json(r, i, 13)) {
      if (!l.is_object()) continue;
      const json name = l.contains("name") && l["name"].is_string() && !l["name"].empty()
                            ? l["name"]
                            : l.value("state", json(nullptr));
      locks.push_back({l.value("kind", json(nullptr)), name});
    }
  }
  const auto dkmh = r.int64_or_null(i, 9);
  return {r.str(i, 0),
          degrees(r, i, 1),
          degrees(r, i, 2),
          state,
          soc ? json(*soc) : json(nullptr),
          dkmh ? json(static_cast<double>(*dkmh) / 10.0) : json(nullptr),
          opt_int(r, i, 11),
          std::move(locks),
          active,
          r.int64_or_null(i, 16).value_or(0)};
}

json alarm_row(const PgResult& r, int i) {
  json a;
  a["id"] = alarm_id({r.str(i, 0), r.str(i, 1), r.int64_or_null(i, 2).value_or(0)});
  a["vehicle_id"] = r.str(i, 0);
  a["kind"] = r.str(i, 3);
  a["transition"] = r.str(i, 4);
  a["at_us"] = opt_int(r, i, 5);
  a["created_at_us"] = opt_int(r, i, 6);
  a["received_at_us"] = opt_int(r, i, 7);
  a["speed_dkmh"] = opt_int(r, i, 8);
  a["soc_pct"] = opt_int(r, i, 9);
  a["lock_kind"] = r.str(i, 10);
  a["detail"] = r.str(i, 11);
  a["acked_by"] = opt_text(r, i, 12);
  a["acked_at_us"] = opt_int(r, i, 13);
  a["active"] = r.boolean(i, 14);
  a["resolved_by"] = opt_text(r, i, 15);
  a["resolved_at_us"] = opt_int(r, i, 16);
  a["resolution_note"] = opt_text(r, i, 17);
  return a;
}

std::string hex(std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(2 * s.size());
  for (const char ch : s) {
    const auto b = static_cast<unsigned char>(ch);
    out += kHex[b >> 4];
    out += kHex[b & 15];
  }
  return out;
}

std::optional<std::string> unhex(std::string_view s) {
  if (s.size() % 2 != 0 || s.size() > 512) return std::nullopt;
  std::string out;
  for (std::size_t i = 0; i < s.size(); i += 2) {
    unsigned v = 0;
    const auto [p, ec] = std::from_chars(s.data() + i, s.data() + i + 2, v, 16);
    if (ec != std::errc() || p != s.data() + i + 2) return std::nullopt;
    out += static_cast<char>(v);
  }
  return out;
}

// A ride's track from the telemetry between its start and end, thinned to at most 500 points
// (every n-th sample) so a long ride does not weigh megabytes.
json ride_track(PgConnection& c, const std::string& vehicle_id, std::int64_t from_us,
                std::int64_t to_us) {
  const PgParam p[] = {vehicle_id, std::to_string(from_us), std::to_string(to_us)};
  const PgResult r = c.query(
      "SELECT lat_e7, lon_e7 FROM telemetry_samples WHERE vehicle_id = $1 AND sampled_at_us "
      "BETWEEN $2::bigint AND $3::bigint AND lat_e7 IS NOT NULL AND lon_e7 IS NOT NULL "
      "ORDER BY sampled_at_us LIMIT 20000",
      p, "ride track");
  const int n = r.rows();
  const int step = n > 500 ? (n + 499) / 500 : 1;
  json track = json::array();
  for (int i = 0; i < n; i += step) track.push_back({degrees(r, i, 0), degrees(r, i, 1)});
  return track;
}

}  // namespace

std::string alarm_id(const AlarmKey& k) {
  return hex(k.vehicle_id) + "." + hex(k.store_id) + "." + std::to_string(k.sequence);
}

std::optional<AlarmKey> parse_alarm_id(std::string_view id) {
  const std::size_t a = id.find('.');
  const std::size_t b = a == std::string_view::npos ? a : id.find('.', a + 1);
  if (b == std::string_view::npos) return std::nullopt;
  auto vehicle = unhex(id.substr(0, a));
  auto store = unhex(id.substr(a + 1, b - a - 1));
  const std::string_view seq = id.substr(b + 1);
  std::int64_t n = 0;
  const auto [p, ec] = std::from_chars(seq.data(), seq.data() + seq.size(), n);
  if (!vehicle || !store || vehicle->empty() || ec != std::errc() || p != seq.data() + seq.size() ||
      n < 0) {
    return std::nullopt;
  }
  return AlarmKey{std::move(*vehicle), std::move(*store), n};
}

json fleet(PgConnection& c) {
  const PgParam p[] = {std::nullopt};
  const PgResult r = c.query(kFleetSql, p, "fleet");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) out.push_back(fleet_row(r, i));
  return out;
}

json fleet_compact(PgConnection& c) {
  const PgParam p[] = {std::nullopt};
  const PgResult r = c.query(kFleetSql, p, "fleet");
  json rows = json::array();
  for (int i = 0; i < r.rows(); ++i) rows.push_back(compact_row(r, i));
  json fields = json::array();
  for (const std::string_view f : kCompactFleetFields) fields.push_back(f);
  return {{"fields", std::move(fields)}, {"vehicles", std::move(rows)}};
}

std::optional<json> vehicle(PgConnection& c, std::string_view vehicle_id) {
  const std::string id(vehicle_id);
  const PgParam p[] = {id};
  const PgResult r = c.query(kFleetSql, p, "vehicle");
  if (r.rows() != 1) return std::nullopt;
  json v = fleet_row(r, 0);

  const PgResult st = c.query(
      "SELECT connection, bus_state, firmware_version, outbox_depth, last_will, "
      "array_to_json(attention), created_at_us, received_at_us FROM status WHERE vehicle_id = $1",
      p, "vehicle status");
  if (st.rows() == 1) {
    v["status"] = {{"connection", st.str(0, 0)},         {"bus_state", st.str(0, 1)},
                   {"firmware_version", st.str(0, 2)},   {"outbox_depth", opt_int(st, 0, 3)},
                   {"last_will", st.boolean(0, 4)},      {"attention", pg_json(st, 0, 5)},
                   {"created_at_us", opt_int(st, 0, 6)}, {"received_at_us", opt_int(st, 0, 7)}};
  } else {
    v["status"] = nullptr;
  }

  const PgResult rides = c.query(
      "SELECT ride_id, started_at_us, ended_at_us, distance_odo_m, distance_gnss_m, "
      "max_speed_dkmh, avg_speed_dkmh, energy_mwh, soc_start_pct, soc_end_pct, partial, "
      "start_lat_e7, start_lon_e7, end_lat_e7, end_lon_e7 FROM rides WHERE vehicle_id = $1 "
      "ORDER BY coalesce(started_at_us, created_at_us) DESC LIMIT 10",
      p, "vehicle rides");
  v["rides"] = json::array();
  for (int i = 0; i < rides.rows(); ++i) {
    json ride = {{"ride_id", rides.str(i, 0)},
                 {"started_at_us", opt_int(rides, i, 1)},
                 {"ended_at_us", opt_int(rides, i, 2)},
                 {"distance_odo_m", opt_int(rides, i, 3)},
                 {"distance_gnss_m", opt_int(rides, i, 4)},
                 {"max_speed_dkmh", opt_int(rides, i, 5)},
                 {"avg_speed_dkmh", opt_int(rides, i, 6)},
                 {"energy_mwh", opt_int(rides, i, 7)},
                 {"soc_start_pct", opt_int(rides, i, 8)},
                 {"soc_end_pct", opt_int(rides, i, 9)},
                 {"partial", rides.boolean(i, 10)},
                 {"start", {degrees(rides, i, 11), degrees(rides, i, 12)}},
                 {"end", {degrees(rides, i, 13), degrees(rides, i, 14)}}};
    const auto from = rides.int64_or_null(i, 1);
    const auto to = rides.int64_or_null(i, 2);
    ride["track"] = from && to ? ride_track(c, id, *from, *to) : json::array();
    v["rides"].push_back(std::move(ride));
  }

  const PgResult faults = c.query(
      "SELECT node, bit, code, name, severity, kind, first_seen_us, last_seen_us, occurrences "
      "FROM fault_events WHERE vehicle_id = $1 ORDER BY created_at_us DESC, sequence DESC "
      "LIMIT 50",
      p, "vehicle faults");
  v["faults"] = json::array();
  for (int i = 0; i < faults.rows(); ++i) {
    v["faults"].push_back({{"node", faults.str(i, 0)},
                           {"bit", opt_int(faults, i, 1)},
                           {"code", opt_int(faults, i, 2)},
                           {"name", faults.str(i, 3)},
                           {"severity", faults.str(i, 4)},
                           {"kind", faults.str(i, 5)},
                           {"first_seen_us", opt_int(faults, i, 6)},
                           {"last_seen_us", opt_int(faults, i, 7)},
                           {"occurrences", opt_int(faults, i, 8)}});
  }

  const PgResult al =
      c.query("SELECT " + std::string(kAlarmColumns) +
                  " WHERE a.vehicle_id = $1 ORDER BY coalesce(a.at_us, a.created_at_us) DESC, "
                  "a.sequence DESC LIMIT 50",
              p, "vehicle alarms");
  v["alarm_history"] = json::array();
  for (int i = 0; i < al.rows(); ++i) v["alarm_history"].push_back(alarm_row(al, i));

  const PgResult cmds = c.query(
      "SELECT c.command_id, c.key_id, c.action, c.target, c.issued_at_us, c.received_at_us, "
      "r.result, r.reason, r.duration_ms FROM commands c LEFT JOIN LATERAL (SELECT result, "
      "reason, duration_ms FROM command_results cr WHERE cr.vehicle_id = c.vehicle_id AND "
      "cr.command_id = c.command_id ORDER BY cr.created_at_us DESC LIMIT 1) r ON true "
      "WHERE c.vehicle_id = $1 ORDER BY c.received_at_us DESC LIMIT 50",
      p, "vehicle commands");
  v["commands"] = json::array();
  for (int i = 0; i < cmds.rows(); ++i) {
    v["commands"].push_back({{"command_id", cmds.str(i, 0)},
                             {"key_id", cmds.str(i, 1)},
                             {"action", cmds.str(i, 2)},
                             {"target", cmds.str(i, 3)},
                             {"issued_at_us", opt_int(cmds, i, 4)},
                             {"received_at_us", opt_int(cmds, i, 5)},
                             {"result", opt_text(cmds, i, 6)},
                             {"reason", opt_text(cmds, i, 7)},
                             {"duration_ms", opt_int(cmds, i, 8)}});
  }

  // What the bike reports of itself in vehicle_state beyond the fleet columns (issue 28's
  // migration 4 of the ingest: locks, faults, active alarms, speed limit in force, assist,
  // bus state). Read as the row's JSON, so a database without those columns yet still works.
  const PgResult full =
      c.query("SELECT to_jsonb(vs) FROM vehicle_state vs WHERE vehicle_id = $1", p, "state");
  json reported = json::object();
  if (full.rows() == 1) {
    const json row = pg_json(full, 0, 0);
    for (const char* k :
         {"locks", "faults", "active_alarms", "speed_limit_dkmh", "assist_name", "bus_state"}) {
      if (row.is_object() && row.contains(k)) reported[k] = row[k];
    }
  }
  v["reported"] = reported;
  // The limit in force and why (ride_api.h): the operator's cap, the slow zones the bike is in.
  v["speed_limit"] = speed_limit(c, id, reported);

  // The console's own commands: who sent each, and the bike's answer.
  const PgResult cc = c.query(
      "SELECT command_id, operator, action, params, issued_at_us, expires_at_us, result, reason, "
      "result_operator, duration_ms, final_state, limit_in_force, result_at_us, key_id "
      "FROM console_commands WHERE vehicle_id = $1 ORDER BY issued_at_us DESC LIMIT 50",
      p, "vehicle console commands");
  v["console_commands"] = json::array();
  for (int i = 0; i < cc.rows(); ++i) {
    v["console_commands"].push_back({{"command_id", cc.str(i, 0)},
                                     {"operator", cc.str(i, 1)},
                                     {"action", cc.str(i, 2)},
                                     {"params", cc.str(i, 3)},
                                     {"issued_at_us", opt_int(cc, i, 4)},
                                     {"expires_at_us", opt_int(cc, i, 5)},
                                     {"result", opt_text(cc, i, 6)},
                                     {"reason", opt_text(cc, i, 7)},
                                     {"result_operator", opt_text(cc, i, 8)},
                                     {"duration_ms", opt_int(cc, i, 9)},
                                     {"final_state", opt_text(cc, i, 10)},
                                     {"limit_in_force", opt_text(cc, i, 11)},
                                     {"result_at_us", opt_int(cc, i, 12)},
                                     {"key_id", cc.str(i, 13)}});
  }
  return v;
}

json alarms(PgConnection& c, int limit) {
  const PgParam p[] = {std::to_string(limit)};
  const PgResult r = c.query("SELECT " + std::string(kAlarmColumns) +
                                 " ORDER BY a.committed_at_us DESC, a.sequence DESC LIMIT $1",
                             p, "alarm feed");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) out.push_back(alarm_row(r, i));
  return out;
}

AckResult ack_alarm(PgConnection& c, const AlarmKey& key, std::string_view operator_name,
                    std::int64_t now_us) {
  const PgParam k[] = {key.vehicle_id, key.store_id, std::to_string(key.sequence)};
  if (c.query("SELECT 1 FROM alarms WHERE vehicle_id = $1 AND store_id = $2 AND sequence = $3", k,
              "find alarm")
          .rows() == 0) {
    return AckResult::NoSuchAlarm;
  }
  const PgParam p[] = {key.vehicle_id, key.store_id, std::to_string(key.sequence),
                       std::string(operator_name), std::to_string(now_us)};
  const PgResult r = c.query(
      "INSERT INTO console_alarm_acks (vehicle_id, store_id, sequence, acked_by, acked_at_us) "
      "VALUES ($1, $2, $3, $4, $5) ON CONFLICT DO NOTHING",
      p, "acknowledge alarm");
  return r.affected() == 1 ? AckResult::Acked : AckResult::AlreadyAcked;
}

std::string to_json_text(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace fleetgw::web
