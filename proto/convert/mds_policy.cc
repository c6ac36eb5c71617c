#include "proto/convert/mds_policy.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

namespace fleetgw::convert {
namespace {

using nlohmann::json;

constexpr double kKmPerMile = 1.609344;

// `doc`'s list under data.<plural>, <plural> or one <singular>, with its JSON path.
std::pair<json, std::string> mds_list(const json& doc, const char* plural, const char* singular) {
  if (doc.contains("data") && doc["data"].is_object() && doc["data"].contains(plural)) {
    return {doc["data"][plural], std::string("data.") + plural};
  }
  if (doc.contains(plural)) return {doc[plural], plural};
  if (doc.contains(singular)) return {json::array({doc[singular]}), singular};
  return {json(), plural};
}

std::string mds_cut(const std::string& text, std::size_t bytes) {
  if (text.size() <= bytes) return text;
  std::size_t end = bytes;
  while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0) == 0x80) --end;
  return text.substr(0, end);
}

std::optional<std::string> mds_ring(const json& ring, const std::string& path, v1::ZoneRing& out) {
  if (!ring.is_array()) return path + ": a ring must be an array of positions";
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const json& p = ring[i];
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!p.is_array() || p.size() < 2 || !p[0].is_number() || !p[1].is_number()) {
      return at + ": not [longitude, latitude]";
    }
    const double lon = p[0].get<double>(), lat = p[1].get<double>();
    if (!std::isfinite(lon) || lon < -180 || lon > 180 || !std::isfinite(lat) || lat < -90 ||
        lat > 90) {
      return at + ": " + p.dump() + " is not a [longitude, latitude] in range";
    }
    out.add_lon_e7(static_cast<std::int32_t>(std::lround(lon * 1e7)));
    out.add_lat_e7(static_cast<std::int32_t>(std::lround(lat * 1e7)));
  }
  return std::nullopt;
}

// Every polygon of a GeoJSON object (FeatureCollection, Feature, Polygon, MultiPolygon) into
// `zone`'s rings and polygon_rings.
std::optional<std::string> mds_shapes(const json& g, const std::string& path, v1::Zone& zone) {
  const json type = g.is_object() ? g.value("type", json()) : json();
  auto polygon = [&](const json& rings, const std::string& at) -> std::optional<std::string> {
    if (!rings.is_array() || rings.empty()) return at + ": a polygon must be an array of rings";
    for (std::size_t r = 0; r < rings.size(); ++r) {
      if (auto e = mds_ring(rings[r], at + "[" + std::to_string(r) + "]", *zone.add_rings())) {
        return e;
      }
    }
    zone.add_polygon_rings(static_cast<std::uint32_t>(rings.size()));
    return std::nullopt;
  };
  if (type == "FeatureCollection" && g.contains("features") && g["features"].is_array()) {
    for (std::size_t i = 0; i < g["features"].size(); ++i) {
      const std::string at = path + ".features[" + std::to_string(i) + "]";
      if (auto e = mds_shapes(g["features"][i], at, zone)) return e;
    }
    return std::nullopt;
  }
  if (type == "Feature") return mds_shapes(g.value("geometry", json()), path + ".geometry", zone);
  const json coords = g.is_object() ? g.value("coordinates", json()) : json();
  if (type == "Polygon") return polygon(coords, path + ".coordinates");
  if (type == "MultiPolygon" && coords.is_array()) {
    for (std::size_t p = 0; p < coords.size(); ++p) {
      if (auto e = polygon(coords[p], path + ".coordinates[" + std::to_string(p) + "]")) return e;
    }
    return std::nullopt;
  }
  return path + ": not a FeatureCollection, Feature, Polygon or MultiPolygon";
}

std::optional<std::string> mds_time(const json& v, const std::string& at, std::int64_t& us) {
  if (v.is_null()) return std::nullopt;
  if (!v.is_number_integer() || v.get<std::int64_t>() < 0) {
    return at + ": " + v.dump() + " is not milliseconds since the epoch";
  }
  us = v.get<std::int64_t>() * 1000;
  return std::nullopt;
}

}  // namespace

std::variant<GbfsZonesImport, std::string> zone_bundle_from_mds(std::string_view policy_text,
                                                                std::string_view geography_text) {
  const json policy_doc = json::parse(policy_text, nullptr, false);
  const json geo_doc = json::parse(geography_text, nullptr, false);
  if (policy_doc.is_discarded()) return std::string("policy: not JSON");
  if (geo_doc.is_discarded()) return std::string("geography: not JSON");
  GbfsZonesImport out;
  auto& notes = out.notes;
  // Geographies by id.
  std::map<std::string, std::pair<const json*, std::string>> geographies;
  const auto [geos, geos_path] = mds_list(geo_doc, "geographies", "geography");
  if (!geos.is_array()) return "geography " + geos_path + ": missing (an array of geographies)";
  for (std::size_t i = 0; i < geos.size(); ++i) {
    const std::string at = geos_path + "[" + std::to_string(i) + "]";
    if (!geos[i].is_object() || !geos[i].contains("geography_id") ||
        !geos[i]["geography_id"].is_string() || !geos[i].contains("geography_json")) {
      return "geography " + at + ": needs a geography_id and a geography_json";
    }
    geographies[geos[i]["geography_id"].get<std::string>()] = {&geos[i], at};
  }
  const auto [policies, policies_path] = mds_list(policy_doc, "policies", "policy");
  if (!policies.is_array()) return "policy " + policies_path + ": missing (an array of policies)";
  v1::ZoneBundle& bundle = out.bundle;
  bundle.set_precedence(v1::ZONE_PRECEDENCE_FIRST_MATCH);
  for (std::size_t p = 0; p < policies.size(); ++p) {
    const json& pol = policies[p];
    const std::string ppath = policies_path + "[" + std::to_string(p) + "]";
    if (!pol.is_object() || !pol.contains("rules") || !pol["rules"].is_array()) {
      return "policy " + ppath + ": needs an array of rules";
    }
    std::int64_t start_us = 0, end_us = 0;
    if (auto e = mds_time(pol.value("start_date", json()), ppath + ".start_date", start_us)) {
      return "policy " + *e;
    }
    if (auto e = mds_time(pol.value("end_date", json()), ppath + ".end_date", end_us)) {
      return "policy " + *e;
    }
    for (std::size_t r = 0; r < pol["rules"].size(); ++r) {
      const json& rule = pol["rules"][r];
      const std::string rpath = ppath + ".rules[" + std::to_string(r) + "]";
      if (!rule.is_object()) return "policy " + rpath + ": a rule must be an object";
      const std::string name = rule.value("name", std::string());
      for (const auto& [key, value] : rule.items()) {
        const std::string at = rpath + "." + key;
        if (key == "rule_type" && value != "speed") {
          return "policy " + at + ": " + value.dump() + " ('" + name +
                 "'): only speed rules are enforced by the bike (refused, not dropped)";
        }
        if (key == "days" || key == "start_time" || key == "end_time") {
          return "policy " + at + " ('" + name +
                 "'): a weekly schedule cannot be expressed (a zone's window is one interval)";
        }
        if (key == "messages" || key == "states") {
          notes.push_back(at + ": no effect on the bike (the limit holds in every state)");
        } else if (key != "rule_type" && key != "rule_id" && key != "name" && key != "rule_units" &&
                   key != "geographies" && key != "vehicle_types" && key != "maximum") {
          return "policy " + at + " ('" + name + "'): unknown or unenforceable rule property '" +
                 key + "' (refused, not dropped)";
        }
      }
      if (rule.value("rule_type", json()) != "speed") {
        return "policy " + rpath + ".rule_type: missing";
      }
      if (rule.contains("vehicle_types")) {
        const json& types = rule["vehicle_types"];
        if (!types.is_array()) return "policy " + rpath + ".vehicle_types: must be an array";
        if (!types.empty() && std::find(types.begin(), types.end(), "bicycle") == types.end()) {
          notes.push_back(rpath + ": not for bicycles (vehicle_types " + types.dump() +
                          "); skipped");
          continue;
        }
      }
      const std::string units = rule.value("rule_units", std::string("kph"));
      if (units != "kph" && units != "mph") {
        return "policy " + rpath + ".rule_units: \"" + units + "\" is not \"kph\" or \"mph\"";
      }
      const json maximum = rule.value("maximum", json());
      if (!maximum.is_number() || !(maximum.get<double>() >= 0)) {
        return "policy " + rpath + ".maximum: " + maximum.dump() + " is not a speed";
      }
      const double kmh = std::floor(maximum.get<double>() * (units == "mph" ? kKmPerMile : 1.0));
      if (kmh > 255) {
        return "policy " + rpath + ".maximum: " + maximum.dump() + " " + units +
               " is over 255 km/h";
      }
      const json geo_ids = rule.value("geographies", json());
      if (!geo_ids.is_array() || geo_ids.empty()) {
        return "policy " + rpath + ".geographies: must name at least one geography";
      }
      for (std::size_t g = 0; g < geo_ids.size(); ++g) {
        const std::string gpath = rpath + ".geographies[" + std::to_string(g) + "]";
        const auto it = geo_ids[g].is_string() ? geographies.find(geo_ids[g].get<std::string>())
                                               : geographies.end();
        if (it == geographies.end()) {
          return "policy " + gpath + ": " + geo_ids[g].dump() + " is not in the Geography";
        }
        const json& geo = *it->second.first;
        v1::Zone& zone = *bundle.add_zones();
        zone.set_id("mds-" + std::to_string(p) + "-" + std::to_string(r) + "-" + std::to_string(g));
        zone.set_kind(v1::ZONE_KIND_RULES);
        zone.set_name(mds_cut(name + " / " + geo.value("name", std::string()), 128));
        zone.set_start_us(start_us);
        zone.set_end_us(end_us);
        v1::ZoneRule& z = *zone.add_rules();
        z.set_ride_start_allowed(true);
        z.set_ride_end_allowed(true);
        z.set_ride_through_allowed(true);
        z.set_maximum_speed_kph(static_cast<std::uint32_t>(kmh));
        if (auto e =
                mds_shapes(geo["geography_json"], it->second.second + ".geography_json", zone)) {
          return "geography " + *e;
        }
      }
    }
  }
  return out;
}

}  // namespace fleetgw::convert
