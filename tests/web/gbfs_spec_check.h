// Test support: a checker of GBFS v3.0 documents, written from the specification's text
// (MobilityData gbfs.md v3.0: "Files", "Field Types", and each file's field table), used by
// the GBFS tests against PostgreSQL rows (gbfs_feeds_test.cc) and against real gateways
// (standards_e2e_test.cc).
//
// Contract:
//  * Each check_*() returns the problems it found, one "<JSON path>: <what>" per problem; an
//    empty list means the document passed. They never throw on any JSON input.
//  * What is checked (REQUIRED fields present with their types; enums; ranges; rules):
//     - every file: last_updated (RFC 3339 timestamp), ttl (non-negative integer), version
//       "3.0", data (object);
//     - gbfs.json: data.feeds, non-empty, each {name in v3.0's feed names, url http(s)}, names
//       unique, system_information listed, vehicle_types listed when vehicle_status is;
//     - system_information: system_id, languages (IETF BCP 47 tags, non-empty), name
//       (localized string), opening_hours, feed_contact_email (an address), timezone (an IANA
//       name); localized strings: non-empty arrays of {text, language};
//     - vehicle_types: vehicle_type_id unique, form_factor and propulsion_type from the enums,
//       max_range_meters (number >= 0) required unless propulsion_type is human,
//       max_permitted_speed a non-negative integer, name localized;
//     - vehicle_status: vehicle_id non-empty and unique, lat/lon in range, is_reserved and
//       is_disabled booleans, vehicle_type_id listed in vehicle_types (when given),
//       current_range_meters (number >= 0) required for motorised types, current_fuel_percent
//       in 0..1, last_reported RFC 3339;
//     - geofencing_zones: a GeoJSON FeatureCollection of Features with MultiPolygon geometry
//       (rings closed, >= 4 positions, [lon, lat] in range, the right-hand rule: exterior
//       rings counter-clockwise, holes clockwise), properties with name (localized), start/end
//       (RFC 3339, end after start), rules; data.global_rules (array, REQUIRED in v3.0); every
//       rule: ride_start_allowed, ride_end_allowed, ride_through_allowed booleans,
//       maximum_speed_kph a non-negative integer, station_parking boolean, vehicle_type_ids
//       strings listed in vehicle_types (when given).
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fleetgw::testing::gbfs_spec {

using Problems = std::vector<std::string>;
using nlohmann::json;

inline const std::set<std::string>& feed_names() {
  static const std::set<std::string> k = {"gbfs",
                                          "gbfs_versions",
                                          "system_information",
                                          "vehicle_types",
                                          "station_information",
                                          "station_status",
                                          "vehicle_status",
                                          "system_alerts",
                                          "system_regions",
                                          "system_pricing_plans",
                                          "geofencing_zones"};
  return k;
}
inline const std::set<std::string>& form_factors() {
  static const std::set<std::string> k = {"bicycle",          "cargo_bicycle",  "car",  "moped",
                                          "scooter_standing", "scooter_seated", "other"};
  return k;
}
inline const std::set<std::string>& propulsion_types() {
  static const std::set<std::string> k = {"human",          "electric_assist",   "electric",
                                          "combustion",     "combustion_diesel", "hybrid",
                                          "plug_in_hybrid", "hydrogen_fuel_cell"};
  return k;
}

inline bool is_timestamp(const json& v) {
  static const std::regex re(
      R"(\d{4}-(0[1-9]|1[0-2])-(0[1-9]|[12]\d|3[01])T([01]\d|2[0-3]):[0-5]\d:[0-5]\d(\.\d+)?(Z|[+-]\d{2}:\d{2}))");
  return v.is_string() && std::regex_match(v.get<std::string>(), re);
}
inline bool is_language(const json& v) {
  static const std::regex re("^[a-z]{2,3}(-[A-Za-z0-9]{2,8})*$");
  return v.is_string() && std::regex_match(v.get<std::string>(), re);
}
inline bool is_non_negative_int(const json& v) {
  return v.is_number_unsigned() || (v.is_number_integer() && v.get<long long>() >= 0);
}

inline void need(Problems& p, const json& obj, const std::string& path, const char* key) {
  if (!obj.is_object() || !obj.contains(key)) p.push_back(path + "." + key + ": REQUIRED, missing");
}

inline void check_localized(Problems& p, const json& v, const std::string& path) {
  if (!v.is_array() || v.empty()) {
    p.push_back(path + ": a localized string must be a non-empty array");
    return;
  }
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!v[i].is_object() || !v[i].contains("text") || !v[i]["text"].is_string()) {
      p.push_back(at + ".text: REQUIRED string");
    }
    if (!v[i].is_object() || !v[i].contains("language") || !is_language(v[i]["language"])) {
      p.push_back(at + ".language: REQUIRED IETF BCP 47 language tag");
    }
  }
}

// Every file's top level.
inline Problems check_envelope(const json& doc) {
  Problems p;
  if (!doc.is_object()) return {"$: a GBFS file is a JSON object"};
  if (!doc.contains("last_updated") || !is_timestamp(doc["last_updated"])) {
    p.push_back("$.last_updated: REQUIRED RFC 3339 timestamp");
  }
  if (!doc.contains("ttl") || !doc["ttl"].is_number_integer() || doc["ttl"].get<long long>() < 0) {
    p.push_back("$.ttl: REQUIRED non-negative integer");
  }
  if (doc.value("version", json()) != "3.0") p.push_back("$.version: REQUIRED \"3.0\"");
  if (!doc.contains("data") || !doc["data"].is_object()) p.push_back("$.data: REQUIRED object");
  return p;
}

inline Problems check_discovery(const json& doc) {
  Problems p = check_envelope(doc);
  if (!p.empty()) return p;
  const json& feeds = doc["data"].value("feeds", json());
  if (!feeds.is_array() || feeds.empty()) return {"$.data.feeds: REQUIRED non-empty array"};
  std::set<std::string> names;
  for (std::size_t i = 0; i < feeds.size(); ++i) {
    const std::string at = "$.data.feeds[" + std::to_string(i) + "]";
    const json& f = feeds[i];
    if (!f.is_object() || !f.contains("name") || !f["name"].is_string() ||
        !feed_names().contains(f["name"].get<std::string>())) {
      p.push_back(at + ".name: REQUIRED, one of v3.0's feed names");
      continue;
    }
    if (!names.insert(f["name"].get<std::string>()).second) p.push_back(at + ".name: repeated");
    if (!f.contains("url") || !f["url"].is_string() ||
        !std::regex_match(f["url"].get<std::string>(), std::regex("^https?://[^ ]+$"))) {
      p.push_back(at + ".url: REQUIRED URL");
    }
  }
  if (!names.contains("system_information")) {
    p.push_back("$.data.feeds: system_information is REQUIRED");
  }
  if (names.contains("vehicle_status") && !names.contains("vehicle_types")) {
    p.push_back("$.data.feeds: vehicle_types is REQUIRED with vehicle_status");
  }
  return p;
}

inline Problems check_system_information(const json& doc) {
  Problems p = check_envelope(doc);
  if (!p.empty()) return p;
  const json& d = doc["data"];
  for (const char* k :
       {"system_id", "languages", "name", "opening_hours", "feed_contact_email", "timezone"}) {
    need(p, d, "$.data", k);
  }
  if (!p.empty()) return p;
  if (!d["system_id"].is_string() || d["system_id"].get<std::string>().empty()) {
    p.push_back("$.data.system_id: a non-empty ID");
  }
  if (!d["languages"].is_array() || d["languages"].empty()) {
    p.push_back("$.data.languages: a non-empty array of language tags");
  } else {
    for (const json& l : d["languages"]) {
      if (!is_language(l)) p.push_back("$.data.languages: " + l.dump() + " is not a language tag");
    }
  }
  check_localized(p, d["name"], "$.data.name");
  if (!d["opening_hours"].is_string() || d["opening_hours"].get<std::string>().empty()) {
    p.push_back("$.data.opening_hours: an OSM opening_hours string");
  }
  if (!d["feed_contact_email"].is_string() ||
      !std::regex_match(d["feed_contact_email"].get<std::string>(),
                        std::regex(R"(^[^@\s]+@[^@\s]+\.[^@\s]+$)"))) {
    p.push_back("$.data.feed_contact_email: an email address");
  }
  if (!d["timezone"].is_string() ||
      !std::regex_match(d["timezone"].get<std::string>(),
                        std::regex(R"(^(UTC|[A-Z][A-Za-z_]+(/[A-Za-z0-9_+-]+)+)$)"))) {
    p.push_back("$.data.timezone: an IANA time zone name");
  }
  return p;
}

// The propulsion type of each vehicle type id (for the cross-file rules).
using TypeTable = std::map<std::string, std::string>;

inline Problems check_vehicle_types(const json& doc, TypeTable* table = nullptr) {
  Problems p = check_envelope(doc);
  if (!p.empty()) return p;
  const json& types = doc["data"].value("vehicle_types", json());
  if (!types.is_array()) return {"$.data.vehicle_types: REQUIRED array"};
  TypeTable seen;
  for (std::size_t i = 0; i < types.size(); ++i) {
    const std::string at = "$.data.vehicle_types[" + std::to_string(i) + "]";
    const json& t = types[i];
    for (const char* k : {"vehicle_type_id", "form_factor", "propulsion_type"}) need(p, t, at, k);
    if (!t.is_object() || !t.contains("vehicle_type_id") || !t["vehicle_type_id"].is_string()) {
      continue;
    }
    const std::string id = t["vehicle_type_id"];
    const std::string prop = t.value("propulsion_type", json("")).is_string()
                                 ? t.value("propulsion_type", std::string())
                                 : std::string();
    if (!seen.emplace(id, prop).second) p.push_back(at + ".vehicle_type_id: repeated");
    if (!form_factors().contains(t.value("form_factor", json("")).is_string()
                                     ? t.value("form_factor", std::string())
                                     : std::string())) {
      p.push_back(at + ".form_factor: not one of v3.0's form factors");
    }
    if (!propulsion_types().contains(prop)) {
      p.push_back(at + ".propulsion_type: not one of v3.0's propulsion types");
    }
    if (prop != "human") {
      if (!t.contains("max_range_meters") || !t["max_range_meters"].is_number() ||
          t["max_range_meters"].get<double>() < 0) {
        p.push_back(at + ".max_range_meters: REQUIRED (non-negative number) unless human");
      }
    }
    if (t.contains("max_permitted_speed") && !is_non_negative_int(t["max_permitted_speed"])) {
      p.push_back(at + ".max_permitted_speed: a non-negative integer");
    }
    if (t.contains("name")) check_localized(p, t["name"], at + ".name");
  }
  if (table) *table = seen;
  return p;
}

inline Problems check_vehicle_status(const json& doc, const TypeTable& types) {
  Problems p = check_envelope(doc);
  if (!p.empty()) return p;
  const json& vehicles = doc["data"].value("vehicles", json());
  if (!vehicles.is_array()) return {"$.data.vehicles: REQUIRED array"};
  std::set<std::string> ids;
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const std::string at = "$.data.vehicles[" + std::to_string(i) + "]";
    const json& v = vehicles[i];
    for (const char* k : {"vehicle_id", "is_reserved", "is_disabled", "lat", "lon"}) {
      need(p, v, at, k);
    }
    if (!v.is_object()) continue;
    if (!v.contains("vehicle_id") || !v["vehicle_id"].is_string() ||
        v["vehicle_id"].get<std::string>().empty()) {
      p.push_back(at + ".vehicle_id: a non-empty ID");
    } else if (!ids.insert(v["vehicle_id"].get<std::string>()).second) {
      p.push_back(at + ".vehicle_id: repeated");
    }
    if (v.contains("lat") && (!v["lat"].is_number() || std::abs(v["lat"].get<double>()) > 90)) {
      p.push_back(at + ".lat: a latitude in -90..90");
    }
    if (v.contains("lon") && (!v["lon"].is_number() || std::abs(v["lon"].get<double>()) > 180)) {
      p.push_back(at + ".lon: a longitude in -180..180");
    }
    for (const char* k : {"is_reserved", "is_disabled"}) {
      if (v.contains(k) && !v[k].is_boolean()) p.push_back(at + "." + k + ": a boolean");
    }
    std::string prop;
    if (!types.empty()) {
      // REQUIRED when the system publishes vehicle_types.
      if (!v.contains("vehicle_type_id") || !v["vehicle_type_id"].is_string() ||
          !types.contains(v["vehicle_type_id"].get<std::string>())) {
        p.push_back(at + ".vehicle_type_id: REQUIRED, an id listed in vehicle_types");
      } else {
        prop = types.at(v["vehicle_type_id"].get<std::string>());
      }
    }
    if (!prop.empty() && prop != "human" &&
        (!v.contains("current_range_meters") || !v["current_range_meters"].is_number() ||
         v["current_range_meters"].get<double>() < 0)) {
      p.push_back(at + ".current_range_meters: REQUIRED (number >= 0) for a motorised type");
    }
    if (v.contains("current_fuel_percent") &&
        (!v["current_fuel_percent"].is_number() || v["current_fuel_percent"].get<double>() < 0 ||
         v["current_fuel_percent"].get<double>() > 1)) {
      p.push_back(at + ".current_fuel_percent: a number in 0..1");
    }
    if (v.contains("last_reported") && !is_timestamp(v["last_reported"])) {
      p.push_back(at + ".last_reported: an RFC 3339 timestamp");
    }
  }
  return p;
}

inline void check_rule(Problems& p, const json& r, const std::string& at, const TypeTable& types) {
  if (!r.is_object()) {
    p.push_back(at + ": a rule is an object");
    return;
  }
  for (const char* k : {"ride_start_allowed", "ride_end_allowed", "ride_through_allowed"}) {
    if (!r.contains(k) || !r[k].is_boolean()) p.push_back(at + "." + k + ": REQUIRED boolean");
  }
  if (r.contains("maximum_speed_kph") && !is_non_negative_int(r["maximum_speed_kph"])) {
    p.push_back(at + ".maximum_speed_kph: a non-negative integer");
  }
  if (r.contains("station_parking") && !r["station_parking"].is_boolean()) {
    p.push_back(at + ".station_parking: a boolean");
  }
  if (r.contains("vehicle_type_ids")) {
    if (!r["vehicle_type_ids"].is_array()) {
      p.push_back(at + ".vehicle_type_ids: an array of ids");
    } else {
      for (const json& id : r["vehicle_type_ids"]) {
        if (!id.is_string() || (!types.empty() && !types.contains(id.get<std::string>()))) {
          p.push_back(at + ".vehicle_type_ids: " + id.dump() + " is not in vehicle_types");
        }
      }
    }
  }
}

// Twice a closed ring's signed area ([lon, lat] positions): > 0 counter-clockwise.
inline double ring_area2(const json& ring) {
  double a = 0;
  for (std::size_t i = 0; i + 1 < ring.size(); ++i) {
    a += ring[i][0].get<double>() * ring[i + 1][1].get<double>() -
         ring[i + 1][0].get<double>() * ring[i][1].get<double>();
  }
  return a;
}

inline void check_multipolygon(Problems& p, const json& g, const std::string& at) {
  if (!g.is_object() || g.value("type", json()) != "MultiPolygon") {
    p.push_back(at + ".type: REQUIRED \"MultiPolygon\"");
    return;
  }
  const json& polys = g.value("coordinates", json());
  if (!polys.is_array() || polys.empty()) {
    p.push_back(at + ".coordinates: a non-empty array of polygons");
    return;
  }
  for (std::size_t i = 0; i < polys.size(); ++i) {
    const json& poly = polys[i];
    if (!poly.is_array() || poly.empty()) {
      p.push_back(at + ".coordinates[" + std::to_string(i) + "]: a polygon is an array of rings");
      continue;
    }
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const std::string rat =
          at + ".coordinates[" + std::to_string(i) + "][" + std::to_string(k) + "]";
      const json& ring = poly[k];
      if (!ring.is_array() || ring.size() < 4) {
        p.push_back(rat + ": a linear ring has at least 4 positions");
        continue;
      }
      bool positions_ok = true;
      for (const json& pos : ring) {
        if (!pos.is_array() || pos.size() < 2 || !pos[0].is_number() || !pos[1].is_number() ||
            std::abs(pos[0].get<double>()) > 180 || std::abs(pos[1].get<double>()) > 90) {
          positions_ok = false;
        }
      }
      if (!positions_ok) {
        p.push_back(rat + ": positions must be [longitude, latitude] in range");
        continue;
      }
      if (ring.front() != ring.back()) p.push_back(rat + ": the ring is not closed");
      const double a = ring_area2(ring);
      if (k == 0 && a <= 0) p.push_back(rat + ": an exterior ring must be counter-clockwise");
      if (k > 0 && a >= 0) p.push_back(rat + ": a hole must be clockwise");
    }
  }
}

inline Problems check_geofencing_zones(const json& doc, const TypeTable& types) {
  Problems p = check_envelope(doc);
  if (!p.empty()) return p;
  const json& d = doc["data"];
  const json& fc = d.value("geofencing_zones", json());
  if (!fc.is_object() || fc.value("type", json()) != "FeatureCollection" ||
      !fc.contains("features") || !fc["features"].is_array()) {
    p.push_back("$.data.geofencing_zones: REQUIRED GeoJSON FeatureCollection with features");
  } else {
    for (std::size_t i = 0; i < fc["features"].size(); ++i) {
      const std::string at = "$.data.geofencing_zones.features[" + std::to_string(i) + "]";
      const json& f = fc["features"][i];
      if (!f.is_object() || f.value("type", json()) != "Feature") {
        p.push_back(at + ".type: REQUIRED \"Feature\"");
        continue;
      }
      check_multipolygon(p, f.value("geometry", json()), at + ".geometry");
      const json& props = f.value("properties", json());
      if (!props.is_object()) {
        p.push_back(at + ".properties: REQUIRED object");
        continue;
      }
      if (props.contains("name")) check_localized(p, props["name"], at + ".properties.name");
      for (const char* k : {"start", "end"}) {
        if (props.contains(k) && !is_timestamp(props[k])) {
          p.push_back(at + ".properties." + k + ": an RFC 3339 timestamp");
        }
      }
      if (props.contains("start") && props.contains("end") && is_timestamp(props["start"]) &&
          is_timestamp(props["end"]) &&
          props["end"].get<std::string>() <= props["start"].get<std::string>()) {
        p.push_back(at + ".properties.end: must be after start");  // same form: text order
      }
      if (props.contains("rules")) {
        if (!props["rules"].is_array()) {
          p.push_back(at + ".properties.rules: an array");
        } else {
          for (std::size_t r = 0; r < props["rules"].size(); ++r) {
            check_rule(p, props["rules"][r], at + ".properties.rules[" + std::to_string(r) + "]",
                       types);
          }
        }
      }
    }
  }
  if (!d.contains("global_rules") || !d["global_rules"].is_array()) {
    p.push_back("$.data.global_rules: REQUIRED array");
  } else {
    for (std::size_t r = 0; r < d["global_rules"].size(); ++r) {
      check_rule(p, d["global_rules"][r], "$.data.global_rules[" + std::to_string(r) + "]", types);
    }
  }
  return p;
}

inline std::string join(const Problems& p) {
  std::string out;
  for (const std::string& s : p) out += "\n  " + s;
  return out;
}

}  // namespace fleetgw::testing::gbfs_spec
