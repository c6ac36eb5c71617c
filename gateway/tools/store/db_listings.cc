#include "gateway/tools/store/db_listings.h"

#include <stdexcept>
#include <string>

#include "gateway/tools/common/time_arg.h"
#include "motinova/can.h"

namespace fleetgw::tools {
namespace {

using nlohmann::json;

const json& field(const json& row, const char* name) {
  static const json kNull;
  const auto it = row.find(name);
  return it == row.end() ? kNull : *it;
}

json time_of(const json& row, const char* name) {
  const json& v = field(row, name);
  return v.is_number_integer() ? json(iso_utc(v.get<std::int64_t>())) : json();
}

json minutes_of(const json& row, const char* seconds_name) {
  const json& v = field(row, seconds_name);
  return v.is_number() ? json(v.get<double>() / 60.0) : json();
}

json double_of(const json& row, const char* name) {
  const json& v = field(row, name);
  return v.is_number() ? json(v.get<double>()) : json();
}

json node_of(const json& row, const char* name) {
  const json& v = field(row, name);
  if (!v.is_number_integer()) return json();
  const auto n = v.get<std::int64_t>();
  if (n < 0 || n > 15) return json("node" + std::to_string(n));
  return json(std::string(motinova::node_name(static_cast<motinova::Node>(n))));
}

Table rides(const std::vector<json>& rows) {
  Table t;
  t.columns = {{"ride_id", "RIDE"},
               {"start", "START (UTC)"},
               {"end", "END (UTC)"},
               {"state", "STATE"},
               {"partial", "PARTIAL"},
               {"duration_min", "MIN", 1},
               {"moving_min", "MOVING MIN", 1},
               {"distance_km", "KM", 2},
               {"avg_speed_kmh", "AVG KM/H", 1},
               {"max_speed_kmh", "MAX KM/H", 1},
               {"energy_wh", "WH", 1},
               {"soc_start_pct", "SOC START %"},
               {"soc_end_pct", "SOC END %"},
               {"faults", "FAULTS"}};
  for (const auto& r : rows) {
    const bool odometer =
        field(r, "start_odo_km").is_number() && field(r, "end_odo_km").is_number();
    const json& partial = field(r, "partial");
    t.rows.push_back(
        {field(r, "ride_id"), time_of(r, "start_us"), time_of(r, "end_us"), field(r, "state"),
         partial.is_number() ? json(partial.get<std::int64_t>() != 0) : json(),
         minutes_of(r, "duration_s"), minutes_of(r, "moving_s"),
         double_of(r, odometer ? "distance_km" : "distance_integrated_km"),
         double_of(r, "avg_speed_kmh"), double_of(r, "max_speed_kmh"), double_of(r, "energy_wh"),
         field(r, "soc_start_pct"), field(r, "soc_end_pct"), field(r, "fault_count")});
  }
  return t;
}

Table faults(const std::vector<json>& rows) {
  Table t;
  t.columns = {{"time", "TIME (UTC)"},
               {"node", "NODE"},
               {"fault", "FAULT"},
               {"code", "CODE"},
               {"severity", "SEVERITY"},
               {"event", "EVENT"},
               {"occurrences", "COUNT"},
               {"first_seen", "FIRST SEEN (UTC)"},
               {"last_seen", "LAST SEEN (UTC)"}};
  for (const auto& r : rows) {
    t.rows.push_back({time_of(r, "at_us"), node_of(r, "node"), field(r, "name"), field(r, "code"),
                      field(r, "severity"), field(r, "event"), field(r, "occurrences"),
                      time_of(r, "first_seen_us"), time_of(r, "last_seen_us")});
  }
  return t;
}

Table commands(const std::vector<json>& rows) {
  Table t;
  t.columns = {{"time", "TIME (UTC)"}, {"command_id", "COMMAND"}, {"result", "RESULT"},
               {"reason", "REASON"},   {"final_state", "LOCK"},   {"duration_ms", "MS"}};
  for (const auto& r : rows) {
    const json& result = field(r, "result");
    t.rows.push_back({time_of(r, "at_us"), field(r, "command_id"),
                      result.is_null() ? field(r, "state") : result, field(r, "reason"),
                      field(r, "final_state"), field(r, "duration_ms")});
  }
  return t;
}

Table alarms(const std::vector<json>& rows) {
  Table t;
  t.columns = {{"time", "TIME (UTC)"}, {"alarm", "ALARM"},    {"transition", "TRANSITION"},
               {"lock", "LOCK"},       {"speed_kmh", "KM/H"}, {"soc_pct", "SOC %", 0},
               {"detail", "DETAIL"}};
  for (const auto& r : rows) {
    const json& speed = field(r, "speed_kmh");
    t.rows.push_back({time_of(r, "ts_us"), field(r, "kind"), field(r, "transition"),
                      node_of(r, "lock_node"),
                      speed.is_number() ? json(speed.get<double>()) : double_of(r, "max_speed_kmh"),
                      double_of(r, "soc_pct"), field(r, "detail")});
  }
  return t;
}

}  // namespace

Table listing_table(std::string_view name, const std::vector<json>& rows) {
  if (name == "rides") return rides(rows);
  if (name == "faults") return faults(rows);
  if (name == "commands") return commands(rows);
  if (name == "alarms") return alarms(rows);
  throw std::invalid_argument("unknown listing '" + std::string(name) + "'");
}

}  // namespace fleetgw::tools
