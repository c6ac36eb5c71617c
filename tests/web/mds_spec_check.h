// Test support: a checker of MDS 2.0 Provider responses, written from the Open Mobility
// Foundation's OpenAPI definitions (openmobilityfoundation/mds-openapi, models/*.yaml: vehicle,
// vehicle-status, event, telemetry, trip, data-types/*; the micromobility mode's vehicle_state
// and event_types enums and its state transitions), used by mds_api_test.cc and the end-to-end
// standards test.
//
// Contract:
//  * Each check_*() returns the problems found, "<JSON path>: <what>"; empty means it passed.
//    They never throw on any JSON input.
//  * What is checked: every REQUIRED member present with its type; UUIDs as the pattern
//    ^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$; timestamps integer ms
//    >= 1514764800000; GPS lat -90..90, lng -180..180, heading 0..360, horizontal_accuracy and
//    speed numbers; vehicle_type, propulsion_types (non-empty, unique), vehicle_state and
//    event_types (non-empty) from the enums; battery_percent 0..100; trip_ids (>= 1 UUID) on
//    events whose types include a trip_* type; telemetry's trip_ids and journey_id present
//    (null or UUID[] / UUID); trip_type from the micromobility enum (rider, rebalance,
//    maintenance); duration and distance non-negative integers; end_time >= start_time; each
//    event's vehicle_state one its first event type leads to (the micromobility transitions);
//    the payload: version "2.0.x", links.next null or a URL, and last_updated (ms) and ttl
//    (integer) on the real-time endpoints.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fleetgw::testing::mds_spec {

using Problems = std::vector<std::string>;
using nlohmann::json;

inline const std::set<std::string>& vehicle_states() {
  static const std::set<std::string> k = {"removed",  "available", "non_operational",
                                          "reserved", "on_trip",   "non_contactable",
                                          "missing",  "elsewhere"};
  return k;
}
inline const std::set<std::string>& event_types() {
  static const std::set<std::string> k = {"agency_drop_off",
                                          "agency_pick_up",
                                          "battery_charged",
                                          "battery_low",
                                          "changed_geographies",
                                          "comms_lost",
                                          "comms_restored",
                                          "compliance_pick_up",
                                          "decommissioned",
                                          "located",
                                          "maintenance",
                                          "maintenance_pick_up",
                                          "not_located",
                                          "off_hours",
                                          "on_hours",
                                          "provider_drop_off",
                                          "rebalance_pick_up",
                                          "reservation_cancel",
                                          "reservation_start",
                                          "system_resume",
                                          "system_suspend",
                                          "trip_cancel",
                                          "trip_end",
                                          "trip_enter_jurisdiction",
                                          "trip_leave_jurisdiction",
                                          "trip_start",
                                          "unspecified"};
  return k;
}
inline const std::set<std::string>& vehicle_types() {
  static const std::set<std::string> k = {
      "bicycle",        "bus",   "cargo_bicycle", "car",
      "delivery_robot", "moped", "motorcycle",    "scooter_standing",
      "scooter_seated", "truck", "other"};
  return k;
}
inline const std::set<std::string>& propulsion_types() {
  static const std::set<std::string> k = {
      "human",  "electric_assist",    "electric",      "combustion", "combustion_diesel",
      "hybrid", "hydrogen_fuel_cell", "plug_in_hybrid"};
  return k;
}
// The states an event type leads to in the micromobility transition table (the types a state
// change lists first).
inline const std::map<std::string, std::set<std::string>>& leads_to() {
  static const std::map<std::string, std::set<std::string>> k = {
      {"trip_start", {"on_trip"}},
      {"trip_end", {"available", "non_operational", "elsewhere"}},
      {"trip_enter_jurisdiction", {"on_trip"}},
      {"trip_leave_jurisdiction", {"elsewhere"}},
      {"reservation_start", {"reserved"}},
      {"reservation_cancel", {"available"}},
      {"comms_lost", {"non_contactable"}},
      {"not_located", {"missing"}},
      {"decommissioned", {"removed"}},
      {"battery_low", {"non_operational"}},
      {"battery_charged", {"available"}}};
  return k;
}

inline bool is_uuid(const json& v) {
  static const std::regex re("^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$");
  return v.is_string() && std::regex_match(v.get<std::string>(), re);
}
inline bool is_timestamp(const json& v) {
  return (v.is_number_integer() || v.is_number_unsigned()) &&
         v.get<long long>() >= 1'514'764'800'000LL;
}
inline bool is_count(const json& v) {
  return v.is_number_unsigned() || (v.is_number_integer() && v.get<long long>() >= 0);
}

inline void need(Problems& p, const json& o, const std::string& at,
                 std::initializer_list<const char*> keys) {
  for (const char* k : keys) {
    if (!o.is_object() || !o.contains(k)) p.push_back(at + "." + k + ": REQUIRED, missing");
  }
}
inline void need_uuid(Problems& p, const json& o, const std::string& at, const char* k) {
  if (o.is_object() && o.contains(k) && !is_uuid(o[k])) p.push_back(at + "." + k + ": a UUID");
}

inline void check_gps(Problems& p, const json& g, const std::string& at) {
  if (!g.is_object()) {
    p.push_back(at + ": a GPS object");
    return;
  }
  if (!g.contains("lat") || !g["lat"].is_number() || std::abs(g["lat"].get<double>()) > 90) {
    p.push_back(at + ".lat: REQUIRED latitude in -90..90");
  }
  if (!g.contains("lng") || !g["lng"].is_number() || std::abs(g["lng"].get<double>()) > 180) {
    p.push_back(at + ".lng: REQUIRED longitude in -180..180");
  }
  if (g.contains("heading") && (!g["heading"].is_number() || g["heading"].get<double>() < 0 ||
                                g["heading"].get<double>() > 360)) {
    p.push_back(at + ".heading: degrees 0..360 clockwise from north");
  }
  for (const char* k : {"horizontal_accuracy", "speed", "altitude", "vertical_accuracy"}) {
    if (g.contains(k) && !g[k].is_number()) p.push_back(at + "." + k + ": a number");
  }
  if (g.contains("horizontal_accuracy") && g["horizontal_accuracy"].is_number() &&
      g["horizontal_accuracy"].get<double>() < 0) {
    p.push_back(at + ".horizontal_accuracy: metres, not negative");
  }
  if (g.contains("satellites") && !is_count(g["satellites"])) {
    p.push_back(at + ".satellites: a non-negative integer");
  }
}

inline void check_battery(Problems& p, const json& o, const std::string& at) {
  if (o.contains("battery_percent") &&
      (!is_count(o["battery_percent"]) || o["battery_percent"].get<long long>() > 100)) {
    p.push_back(at + ".battery_percent: an integer 0..100");
  }
}

inline Problems check_vehicle(const json& v, const std::string& at = "$") {
  Problems p;
  need(p, v, at,
       {"device_id", "provider_id", "vehicle_id", "vehicle_type", "propulsion_types",
        "accessibility_options"});
  if (!v.is_object()) return p;
  need_uuid(p, v, at, "device_id");
  need_uuid(p, v, at, "provider_id");
  if (v.contains("vehicle_id") && !v["vehicle_id"].is_string()) {
    p.push_back(at + ".vehicle_id: a string");
  }
  if (v.contains("vehicle_type") &&
      (!v["vehicle_type"].is_string() ||
       !vehicle_types().contains(v["vehicle_type"].get<std::string>()))) {
    p.push_back(at + ".vehicle_type: not one of MDS's vehicle types");
  }
  if (v.contains("propulsion_types")) {
    const json& t = v["propulsion_types"];
    std::set<std::string> seen;
    bool ok = t.is_array() && !t.empty();
    for (const json& x : ok ? t : json::array()) {
      ok = ok && x.is_string() && propulsion_types().contains(x.get<std::string>()) &&
           seen.insert(x.get<std::string>()).second;
    }
    if (!ok) p.push_back(at + ".propulsion_types: a non-empty set of MDS propulsion types");
  }
  if (v.contains("accessibility_options") && !v["accessibility_options"].is_array() &&
      !v["accessibility_options"].is_object()) {
    p.push_back(at + ".accessibility_options: an array or an object");
  }
  for (const char* k : {"battery_capacity", "fuel_capacity", "maximum_speed"}) {
    if (v.contains(k) && !is_count(v[k])) p.push_back(at + "." + k + ": a non-negative integer");
  }
  return p;
}

inline Problems check_event(const json& e, const std::string& at = "$") {
  Problems p;
  need(p, e, at,
       {"device_id", "provider_id", "event_id", "vehicle_state", "event_types", "timestamp",
        "location"});
  if (!e.is_object()) return p;
  for (const char* k : {"device_id", "provider_id", "event_id"}) need_uuid(p, e, at, k);
  if (e.contains("vehicle_state") &&
      (!e["vehicle_state"].is_string() ||
       !vehicle_states().contains(e["vehicle_state"].get<std::string>()))) {
    p.push_back(at + ".vehicle_state: not one of the micromobility states");
  }
  bool trip_type = false;
  if (e.contains("event_types")) {
    const json& t = e["event_types"];
    bool ok = t.is_array() && !t.empty();
    for (const json& x : ok ? t : json::array()) {
      ok = ok && x.is_string() && event_types().contains(x.get<std::string>());
      if (x.is_string() && x.get<std::string>().starts_with("trip_")) trip_type = true;
    }
    if (!ok) p.push_back(at + ".event_types: a non-empty array of micromobility event types");
    if (ok && e.contains("vehicle_state") && e["vehicle_state"].is_string()) {
      const auto it = leads_to().find(t[0].get<std::string>());
      if (it != leads_to().end() && !it->second.contains(e["vehicle_state"].get<std::string>())) {
        p.push_back(at + ": " + t[0].get<std::string>() + " does not lead to " +
                    e["vehicle_state"].get<std::string>());
      }
    }
  }
  if (e.contains("timestamp") && !is_timestamp(e["timestamp"])) {
    p.push_back(at + ".timestamp: integer milliseconds since 1970, from 2018");
  }
  if (e.contains("location")) check_gps(p, e["location"], at + ".location");
  check_battery(p, e, at);
  if (trip_type) {
    bool ok = e.contains("trip_ids") && e["trip_ids"].is_array() && !e["trip_ids"].empty();
    for (const json& id : ok ? e["trip_ids"] : json::array()) ok = ok && is_uuid(id);
    if (!ok) p.push_back(at + ".trip_ids: REQUIRED (>= 1 UUID) with a trip_* event type");
  }
  return p;
}

inline Problems check_telemetry(const json& t, const std::string& at = "$") {
  Problems p;
  need(p, t, at,
       {"device_id", "provider_id", "telemetry_id", "timestamp", "trip_ids", "journey_id",
        "location"});
  if (!t.is_object()) return p;
  for (const char* k : {"device_id", "provider_id", "telemetry_id"}) need_uuid(p, t, at, k);
  if (t.contains("timestamp") && !is_timestamp(t["timestamp"])) {
    p.push_back(at + ".timestamp: integer milliseconds since 1970, from 2018");
  }
  if (t.contains("trip_ids") && !t["trip_ids"].is_null()) {
    bool ok = t["trip_ids"].is_array();
    for (const json& id : ok ? t["trip_ids"] : json::array()) ok = ok && is_uuid(id);
    if (!ok) p.push_back(at + ".trip_ids: null or an array of UUIDs");
  }
  if (t.contains("journey_id") && !t["journey_id"].is_null() && !is_uuid(t["journey_id"])) {
    p.push_back(at + ".journey_id: null or a UUID");
  }
  if (t.contains("location")) check_gps(p, t["location"], at + ".location");
  check_battery(p, t, at);
  return p;
}

inline Problems check_vehicle_status(const json& s, const std::string& at = "$") {
  Problems p;
  need(p, s, at, {"device_id", "provider_id", "last_event", "last_telemetry"});
  if (!s.is_object()) return p;
  need_uuid(p, s, at, "device_id");
  need_uuid(p, s, at, "provider_id");
  if (s.contains("last_event")) {
    for (auto& x : check_event(s["last_event"], at + ".last_event")) p.push_back(x);
  }
  if (s.contains("last_telemetry")) {
    for (auto& x : check_telemetry(s["last_telemetry"], at + ".last_telemetry")) p.push_back(x);
  }
  return p;
}

inline Problems check_trip(const json& t, const std::string& at = "$") {
  Problems p;
  need(p, t, at,
       {"provider_id", "device_id", "trip_id", "start_time", "end_time", "start_location",
        "end_location", "duration", "distance"});
  if (!t.is_object()) return p;
  for (const char* k : {"provider_id", "device_id", "trip_id"}) need_uuid(p, t, at, k);
  for (const char* k : {"start_time", "end_time", "publication_time"}) {
    if (t.contains(k) && !is_timestamp(t[k])) p.push_back(at + "." + k + ": a timestamp (ms)");
  }
  if (t.contains("start_time") && t.contains("end_time") && is_timestamp(t["start_time"]) &&
      is_timestamp(t["end_time"]) &&
      t["end_time"].get<long long>() < t["start_time"].get<long long>()) {
    p.push_back(at + ".end_time: before start_time");
  }
  for (const char* k : {"start_location", "end_location"}) {
    if (t.contains(k)) check_gps(p, t[k], at + "." + k);
  }
  for (const char* k : {"duration", "distance"}) {
    if (t.contains(k) && !is_count(t[k])) p.push_back(at + "." + k + ": a non-negative integer");
  }
  if (t.contains("trip_type")) {
    static const std::set<std::string> kTypes = {"rider", "rebalance", "maintenance"};
    const json list = t["trip_type"].is_array() ? t["trip_type"] : json::array({t["trip_type"]});
    for (const json& x : list) {
      if (!x.is_string() || !kTypes.contains(x.get<std::string>())) {
        p.push_back(at + ".trip_type: not one of rider, rebalance, maintenance");
      }
    }
  }
  return p;
}

// A whole response: the payload's envelope and each item of `key` by `item`.
template <class Fn>
Problems check_payload(const json& body, const std::string& key, bool realtime, Fn item) {
  Problems p;
  if (!body.is_object()) return {"$: a JSON object"};
  if (!body.contains("version") || !body["version"].is_string() ||
      !std::regex_match(body["version"].get<std::string>(), std::regex(R"(^2\.0\.\d+$)"))) {
    p.push_back("$.version: \"2.0.x\"");
  }
  if (body.contains("links")) {
    const json& next = body["links"].value("next", json());
    if (!next.is_null() && (!next.is_string() || !next.get<std::string>().starts_with("http"))) {
      p.push_back("$.links.next: null or a URL");
    }
  }
  if (realtime) {
    if (!body.contains("last_updated") || !is_timestamp(body["last_updated"])) {
      p.push_back("$.last_updated: REQUIRED timestamp (ms)");
    }
    if (!body.contains("ttl") || !is_count(body["ttl"])) {
      p.push_back("$.ttl: REQUIRED non-negative integer");
    }
  }
  if (!body.contains(key) || !body[key].is_array()) {
    p.push_back("$." + key + ": REQUIRED array");
    return p;
  }
  for (std::size_t i = 0; i < body[key].size(); ++i) {
    for (auto& x : item(body[key][i], "$." + key + "[" + std::to_string(i) + "]")) {
      p.push_back(x);
    }
  }
  return p;
}

inline std::string join(const Problems& p) {
  std::string out;
  for (const std::string& s : p) out += "\n  " + s;
  return out;
}

}  // namespace fleetgw::testing::mds_spec
