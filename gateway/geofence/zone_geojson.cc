#include "gateway/geofence/zone_geojson.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "gateway/common/untrusted_text.h"
#include "gateway/geofence/zone_bundle.h"

namespace fleetgw::geofence {
namespace {

using nlohmann::json;

std::optional<v1::ZoneKind> geojson_kind(std::string_view name) {
  if (name == "operating_area") return v1::ZONE_KIND_OPERATING_AREA;
  if (name == "slow") return v1::ZONE_KIND_SLOW;
  if (name == "no_ride") return v1::ZONE_KIND_NO_RIDE;
  if (name == "no_parking") return v1::ZONE_KIND_NO_PARKING;
  if (name == "no_start") return v1::ZONE_KIND_NO_START;  // issue 27
  return std::nullopt;
}

// One GeoJSON ring into `out`, or why not.
std::optional<std::string> geojson_ring(const json& ring, v1::ZoneRing& out) {
  if (!ring.is_array()) return "not an array of positions";
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const json& pos = ring[i];
    const std::string where = "position " + std::to_string(i);
    if (!pos.is_array() || pos.size() < 2 || !pos[0].is_number() || !pos[1].is_number()) {
      return where + ": not [longitude, latitude]";
    }
    const double lon = pos[0].get<double>(), lat = pos[1].get<double>();
    if (!std::isfinite(lon) || lon < -180 || lon > 180) {
      return where + ": longitude " + pos[0].dump() + " is not a number in -180..180";
    }
    if (!std::isfinite(lat) || lat < -90 || lat > 90) {
      return where + ": latitude " + pos[1].dump() + " is not a number in -90..90";
    }
    out.add_lon_e7(static_cast<std::int32_t>(std::lround(lon * 1e7)));
    out.add_lat_e7(static_cast<std::int32_t>(std::lround(lat * 1e7)));
  }
  return std::nullopt;
}

// The rings of a Polygon's coordinates into `zone`.
std::optional<std::string> geojson_polygon(const json& rings, v1::Zone& zone,
                                           const std::string& where) {
  if (!rings.is_array()) return where + ": polygon coordinates are not an array of rings";
  for (const json& ring : rings) {
    const std::string at = where + ", ring " + std::to_string(zone.rings_size());
    if (auto error = geojson_ring(ring, *zone.add_rings())) return at + ": " + *error;
  }
  return std::nullopt;
}

std::optional<std::string> geojson_feature(const json& f, std::size_t index, v1::Zone& zone) {
  std::string where = "feature " + std::to_string(index);
  if (!f.is_object() || f.value("type", json()) != "Feature") return where + ": not a Feature";
  const json props =
      f.contains("properties") && f["properties"].is_object() ? f["properties"] : json::object();
  const json id = props.contains("id") ? props["id"] : f.value("id", json());
  if (!id.is_string()) return where + ": no string \"id\" in its properties";
  zone.set_id(id.get<std::string>());
  where += " ('" + common::untrusted_excerpt(zone.id(), 64) + "')";
  const json kind = props.value("kind", json());
  const auto k = kind.is_string() ? geojson_kind(kind.get<std::string>()) : std::nullopt;
  if (!k) {
    return where +
           ": \"kind\" must be \"operating_area\", \"slow\", \"no_ride\", \"no_parking\" or "
           "\"no_start\"";
  }
  zone.set_kind(*k);
  if (props.contains("name")) {
    if (!props["name"].is_string()) return where + ": \"name\" is not a string";
    zone.set_name(props["name"].get<std::string>());
  }
  if (props.contains("speed_limit_kmh")) {
    const json& limit = props["speed_limit_kmh"];
    if (!limit.is_number_unsigned() || limit.get<std::uint64_t>() > 255) {
      return where + ": \"speed_limit_kmh\" must be a whole number of km/h in 0..255";
    }
    zone.set_speed_limit_kmh(limit.get<std::uint32_t>());
  }
  const json geometry = f.value("geometry", json());
  if (!geometry.is_object()) return where + ": no geometry";
  const json type = geometry.value("type", json());
  const json coords = geometry.value("coordinates", json());
  if (type == "Polygon") return geojson_polygon(coords, zone, where);
  if (type == "MultiPolygon" && coords.is_array()) {
    for (const json& polygon : coords) {
      if (auto error = geojson_polygon(polygon, zone, where)) return error;
    }
    return std::nullopt;
  }
  return where + ": geometry must be a Polygon or a MultiPolygon";
}

}  // namespace

std::variant<v1::ZoneBundle, std::string> bundle_from_geojson(std::string_view text,
                                                              std::uint64_t version,
                                                              Micros issued_at) {
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return std::string("not JSON");
  if (!doc.is_object() || doc.value("type", json()) != "FeatureCollection" ||
      !doc.contains("features") || !doc["features"].is_array()) {
    return std::string("not a GeoJSON FeatureCollection with a \"features\" array");
  }
  v1::ZoneBundle bundle;
  bundle.set_version(version);
  bundle.set_issued_at_us(issued_at.count());
  const json& features = doc["features"];
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (auto error = geojson_feature(features[i], i, *bundle.add_zones())) return *error;
  }
  // The gateway's own rules, so a bundle signed here is one it accepts.
  auto compiled = compile_zones(bundle);
  if (auto* error = std::get_if<std::string>(&compiled)) return *error;
  return bundle;
}

}  // namespace fleetgw::geofence
