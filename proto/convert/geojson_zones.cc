// GeoJSON zones for the backend (geojson_zones.h).
#include "proto/convert/geojson_zones.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <utility>
#include <vector>

namespace fleetgw::convert {
namespace {

using nlohmann::json;

constexpr std::size_t kGeojsonMaxZones = 4096;
constexpr std::size_t kGeojsonMaxVertices = 100'000;
constexpr std::size_t kGeojsonMaxNameBytes = 128;
constexpr std::int64_t kGeojsonMaxLonSpanE7 = 1'800'000'000;
constexpr double kGeojsonMinRingWidthM = 0.1;
constexpr double kGeojsonMinRingAreaM2 = 1.0;
constexpr double kGeojsonMPerE7 = 6'371'008.8 * M_PI / 180.0 * 1e-7;

std::optional<v1::ZoneKind> geojson_kind_named(std::string_view name) {
  if (name == "operating_area") return v1::ZONE_KIND_OPERATING_AREA;
  if (name == "slow") return v1::ZONE_KIND_SLOW;
  if (name == "no_ride") return v1::ZONE_KIND_NO_RIDE;
  if (name == "no_parking") return v1::ZONE_KIND_NO_PARKING;
  if (name == "no_start") return v1::ZONE_KIND_NO_START;
  return std::nullopt;
}

std::string geojson_kind_name(v1::ZoneKind k) {
  switch (k) {
    case v1::ZONE_KIND_OPERATING_AREA:
      return "operating_area";
    case v1::ZONE_KIND_SLOW:
      return "slow";
    case v1::ZONE_KIND_NO_RIDE:
      return "no_ride";
    case v1::ZONE_KIND_NO_PARKING:
      return "no_parking";
    case v1::ZONE_KIND_NO_START:
      return "no_start";
    case v1::ZONE_KIND_RULES:
      return "rules";
    default:
      return "unknown";
  }
}

bool geojson_zone_id_ok(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

std::optional<std::string> geojson_read_ring(const json& ring, const std::string& at,
                                             v1::ZoneRing& out) {
  if (!ring.is_array()) return at + ": not an array of positions";
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const json& pos = ring[i];
    const std::string where = at + "[" + std::to_string(i) + "]";
    if (!pos.is_array() || pos.size() < 2 || !pos[0].is_number() || !pos[1].is_number()) {
      return where + ": not [longitude, latitude]";
    }
    const double lon = pos[0].get<double>(), lat = pos[1].get<double>();
    if (!std::isfinite(lon) || lon < -180 || lon > 180) {
      return where + ": longitude " + pos[0].dump() + " is not in -180..180";
    }
    if (!std::isfinite(lat) || lat < -90 || lat > 90) {
      return where + ": latitude " + pos[1].dump() + " is not in -90..90";
    }
    out.add_lon_e7(static_cast<std::int32_t>(std::lround(lon * 1e7)));
    out.add_lat_e7(static_cast<std::int32_t>(std::lround(lat * 1e7)));
  }
  return std::nullopt;
}

std::optional<std::string> geojson_read_polygon(const json& rings, const std::string& at,
                                                v1::Zone& zone) {
  if (!rings.is_array()) return at + ": not an array of rings";
  for (std::size_t r = 0; r < rings.size(); ++r) {
    if (auto e =
            geojson_read_ring(rings[r], at + "[" + std::to_string(r) + "]", *zone.add_rings())) {
      return e;
    }
  }
  return std::nullopt;
}

std::optional<std::string> geojson_read_feature(const json& f, const std::string& at,
                                                v1::Zone& zone) {
  if (!f.is_object() || f.value("type", json()) != "Feature") return at + ": not a Feature";
  const json props =
      f.contains("properties") && f["properties"].is_object() ? f["properties"] : json::object();
  const json id = props.contains("id") ? props["id"] : f.value("id", json());
  if (!id.is_string()) return at + ".properties.id: missing (a string naming the zone)";
  zone.set_id(id.get<std::string>());
  const json kind = props.value("kind", json());
  const auto k = kind.is_string() ? geojson_kind_named(kind.get<std::string>()) : std::nullopt;
  if (!k) {
    return at +
           ".properties.kind: must be \"operating_area\", \"slow\", \"no_ride\", \"no_parking\" "
           "or \"no_start\"";
  }
  zone.set_kind(*k);
  if (props.contains("name")) {
    if (!props["name"].is_string()) return at + ".properties.name: not a string";
    zone.set_name(props["name"].get<std::string>());
  }
  if (props.contains("speed_limit_kmh")) {
    const json& limit = props["speed_limit_kmh"];
    if (!limit.is_number_unsigned() || limit.get<std::uint64_t>() > 255) {
      return at + ".properties.speed_limit_kmh: must be a whole number of km/h in 0..255";
    }
    zone.set_speed_limit_kmh(limit.get<std::uint32_t>());
  }
  const json geometry = f.value("geometry", json());
  if (!geometry.is_object()) return at + ".geometry: missing";
  const json type = geometry.value("type", json());
  const json coords = geometry.value("coordinates", json());
  const std::string c_at = at + ".geometry.coordinates";
  if (type == "Polygon") return geojson_read_polygon(coords, c_at, zone);
  if (type == "MultiPolygon") {
    if (!coords.is_array()) return c_at + ": not an array of polygons";
    for (std::size_t p = 0; p < coords.size(); ++p) {
      const int before = zone.rings_size();
      if (auto e = geojson_read_polygon(coords[p], c_at + "[" + std::to_string(p) + "]", zone))
        return e;
      zone.add_polygon_rings(static_cast<std::uint32_t>(zone.rings_size() - before));
    }
    return std::nullopt;
  }
  return at + ".geometry.type: must be Polygon or MultiPolygon";
}

// The ring's path in the uploaded geometry: coordinates[r] for a Polygon, coordinates[p][r]
// for a MultiPolygon (polygon_rings says how rings group).
std::string geojson_ring_path(const v1::Zone& z, int ring) {
  if (z.polygon_rings_size() == 0) return ".geometry.coordinates[" + std::to_string(ring) + "]";
  int p = 0, first = 0;
  while (p < z.polygon_rings_size() && ring >= first + static_cast<int>(z.polygon_rings(p))) {
    first += static_cast<int>(z.polygon_rings(p));
    ++p;
  }
  return ".geometry.coordinates[" + std::to_string(p) + "][" + std::to_string(ring - first) + "]";
}

struct GeojsonVertex {
  std::int64_t lat, lon;
  bool operator==(const GeojsonVertex&) const = default;
};

// The gateway's ring rules (gateway/geofence/zone_bundle.cc ring_of), from the same bytes.
std::optional<std::string> geojson_check_ring(const v1::ZoneRing& r) {
  if (r.lat_e7_size() != r.lon_e7_size())
    return std::string("latitudes and longitudes differ in number");
  std::vector<GeojsonVertex> ring;
  std::int64_t lo = INT64_MAX, hi = INT64_MIN;
  for (int i = 0; i < r.lat_e7_size(); ++i) {
    const GeojsonVertex v{r.lat_e7(i), r.lon_e7(i)};
    lo = std::min(lo, v.lon);
    hi = std::max(hi, v.lon);
    if (ring.empty() || !(ring.back() == v)) ring.push_back(v);
  }
  if (ring.size() > 1 && ring.back() == ring.front()) ring.pop_back();
  std::vector<GeojsonVertex> distinct;
  for (const auto& v : ring) {
    if (std::find(distinct.begin(), distinct.end(), v) == distinct.end()) distinct.push_back(v);
    if (distinct.size() >= 3) break;
  }
  if (distinct.size() < 3) {
    return "ring with " + std::to_string(distinct.size()) + " distinct points (at least 3 needed)";
  }
  if (hi - lo > kGeojsonMaxLonSpanE7) {
    return std::string(
        "ring spans more than 180 degrees of longitude (no zone may cross the "
        "antimeridian)");
  }
  // On the plane tangent at the first vertex, metres.
  const GeojsonVertex o = ring.front();
  const double kx = std::cos(static_cast<double>(o.lat) * 1e-7 * M_PI / 180.0) * kGeojsonMPerE7;
  auto local = [&](const GeojsonVertex& v) {
    return std::pair<double, double>{static_cast<double>(v.lon - o.lon) * kx,
                                     static_cast<double>(v.lat - o.lat) * kGeojsonMPerE7};
  };
  double bx = 0, by = 0;
  for (const auto& v : ring) {
    const auto [x, y] = local(v);
    if (x * x + y * y > bx * bx + by * by) {
      bx = x;
      by = y;
    }
  }
  const double length = std::hypot(bx, by);
  const bool line =
      !(length > 0) || std::all_of(ring.begin(), ring.end(), [&](const GeojsonVertex& v) {
        const auto [x, y] = local(v);
        return std::abs(bx * y - by * x) / length < kGeojsonMinRingWidthM;
      });
  if (line) return std::string("ring's points all lie on one line (it encloses no area)");
  double twice = 0;
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const auto [x0, y0] = local(ring[i]);
    const auto [x1, y1] = local(ring[(i + 1) % ring.size()]);
    twice += x0 * y1 - x1 * y0;
  }
  if (!(std::abs(twice / 2) >= kGeojsonMinRingAreaM2)) {
    return std::string("ring encloses less than 1 square metre (its edges retrace or cross)");
  }
  return std::nullopt;
}

}  // namespace

std::variant<v1::ZoneBundle, std::string> zone_bundle_from_geojson(std::string_view json_text) {
  const json doc = json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return std::string("not JSON");
  if (!doc.is_object() || doc.value("type", json()) != "FeatureCollection") {
    return std::string("type: not a GeoJSON FeatureCollection (nor a GBFS geofencing_zones.json)");
  }
  if (!doc.contains("features") || !doc["features"].is_array()) {
    return std::string("features: missing (an array of Features)");
  }
  v1::ZoneBundle bundle;
  bundle.set_precedence(v1::ZONE_PRECEDENCE_UNION);
  const json& features = doc["features"];
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (auto e = geojson_read_feature(features[i], "features[" + std::to_string(i) + "]",
                                      *bundle.add_zones())) {
      return *e;
    }
  }
  return bundle;
}

std::optional<std::string> check_zone_bundle(const v1::ZoneBundle& bundle,
                                             std::string_view features_path) {
  if (static_cast<std::size_t>(bundle.zones_size()) > kGeojsonMaxZones) {
    return std::string(features_path) + ": " + std::to_string(bundle.zones_size()) +
           " zones, at most " + std::to_string(kGeojsonMaxZones);
  }
  std::size_t vertices = 0;
  for (const auto& z : bundle.zones()) {
    for (const auto& r : z.rings()) vertices += static_cast<std::size_t>(r.lat_e7_size());
  }
  if (vertices > kGeojsonMaxVertices) {
    return std::string(features_path) + ": " + std::to_string(vertices) + " vertices, at most " +
           std::to_string(kGeojsonMaxVertices);
  }
  std::set<std::string> ids;
  for (int i = 0; i < bundle.zones_size(); ++i) {
    const v1::Zone& z = bundle.zones(i);
    const std::string at = std::string(features_path) + "[" + std::to_string(i) + "]";
    if (!geojson_zone_id_ok(z.id())) return at + ".properties.id: must be 1..64 of [A-Za-z0-9._-]";
    if (!ids.insert(z.id()).second) return at + ".properties.id: '" + z.id() + "' repeated";
    if (z.name().size() > kGeojsonMaxNameBytes) return at + ".properties.name: more than 128 bytes";
    if (z.kind() == v1::ZONE_KIND_SLOW && (z.speed_limit_kmh() < 1 || z.speed_limit_kmh() > 255)) {
      return at + ".properties.speed_limit_kmh: a slow zone needs a limit in 1..255 km/h";
    }
    if (z.kind() != v1::ZONE_KIND_SLOW && z.speed_limit_kmh() != 0) {
      return at + ".properties.speed_limit_kmh: only for slow zones";
    }
    if (z.rings_size() == 0) return at + ".geometry.coordinates: no ring";
    for (int r = 0; r < z.rings_size(); ++r) {
      if (auto e = geojson_check_ring(z.rings(r))) return at + geojson_ring_path(z, r) + ": " + *e;
    }
  }
  return std::nullopt;
}

json geojson_from_zone_bundle(const v1::ZoneBundle& bundle) {
  json features = json::array();
  for (const v1::Zone& z : bundle.zones()) {
    auto ring_coords = [&](int r) {
      json ring = json::array();
      const v1::ZoneRing& zr = z.rings(r);
      for (int i = 0; i < zr.lat_e7_size(); ++i) {
        ring.push_back({zr.lon_e7(i) * 1e-7, zr.lat_e7(i) * 1e-7});
      }
      return ring;
    };
    json polygons = json::array();
    if (z.polygon_rings_size() == 0) {
      json poly = json::array();
      for (int r = 0; r < z.rings_size(); ++r) poly.push_back(ring_coords(r));
      polygons.push_back(std::move(poly));
    } else {
      int r = 0;
      for (const auto n : z.polygon_rings()) {
        json poly = json::array();
        for (std::uint32_t k = 0; k < n && r < z.rings_size(); ++k)
          poly.push_back(ring_coords(r++));
        polygons.push_back(std::move(poly));
      }
    }
    json props = {{"id", z.id()}, {"name", z.name()}, {"kind", geojson_kind_name(z.kind())}};
    if (z.kind() == v1::ZONE_KIND_SLOW) props["speed_limit_kmh"] = z.speed_limit_kmh();
    if (z.kind() == v1::ZONE_KIND_RULES && z.rules_size() > 0) {
      const v1::ZoneRule& rule = z.rules(0);
      std::string s;
      if (!rule.ride_through_allowed()) s += "no riding; ";
      if (!rule.ride_start_allowed()) s += "no start; ";
      if (!rule.ride_end_allowed()) s += "no parking; ";
      if (rule.has_maximum_speed_kph()) {
        s += "max " + std::to_string(rule.maximum_speed_kph()) + " km/h; ";
      }
      if (s.empty()) s = "every ride allowed";
      if (s.ends_with("; ")) s.resize(s.size() - 2);
      props["rule"] = s;
    }
    features.push_back({{"type", "Feature"},
                        {"properties", props},
                        {"geometry", {{"type", "MultiPolygon"}, {"coordinates", polygons}}}});
  }
  return {{"type", "FeatureCollection"}, {"features", features}};
}

}  // namespace fleetgw::convert
