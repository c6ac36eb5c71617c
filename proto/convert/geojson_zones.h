// GeoJSON <-> fleetgw.v1.ZoneBundle for the backend (issue 28: the console's zones page), pure
// like gbfs_zones.h: proto/ and nlohmann-json only, no gateway code, no I/O, no clock, no
// signing. The bike's own tool (`fleetgw zones sign`, gateway/geofence/zone_geojson.cc) reads
// the same GeoJSON; the gateway's compile_zones() stays the final judge of a bundle.
//
// API
//  * zone_bundle_from_geojson(text): a GeoJSON FeatureCollection (RFC 7946, what geojson.io and
//    QGIS write), one zone per Feature: properties "id" (or the Feature's own string "id"),
//    "kind" (operating_area, slow, no_ride, no_parking, no_start), optional "name" and
//    "speed_limit_kmh" (slow zones: a whole number 1..255); geometry Polygon or MultiPolygon
//    with [longitude, latitude] positions (rounded to 1e-7 degrees). Precedence UNION;
//    version, issued_at_us and vehicle_id are left for the caller. A MultiPolygon's polygons
//    are kept apart in polygon_rings.
//  * check_zone_bundle(bundle, features_path): what the gateway refuses in a bundle's zones,
//    checked here first so the server never signs one the bikes drop: at most 4,096 zones and
//    100,000 vertices; ids 1..64 of [A-Za-z0-9._-], unique; names at most 128 bytes; a slow
//    zone's limit 1..255 and no limit on other kinds; at least one ring; each ring with at
//    least 3 distinct vertices, within 180 degrees of longitude, not all on one line (0.1 m),
//    enclosing at least 1 square metre. The error names the place as a JSON path of the
//    uploaded document: `<features_path>[3].geometry.coordinates[0]: ring with 2 distinct
//    points (at least 3 needed)` (MultiPolygon: coordinates[p][r]).
//  * geojson_from_zone_bundle(bundle): the zones as a FeatureCollection for a map (properties:
//    id, name, kind -- operating_area, slow, no_ride, no_parking, no_start or rules --,
//    speed_limit_kmh, and for GBFS rule zones a one-line summary of the first rule).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <variant>

#include <nlohmann/json.hpp>

#include "fleetgw/v1/zones.pb.h"

namespace fleetgw::convert {

std::variant<v1::ZoneBundle, std::string> zone_bundle_from_geojson(std::string_view json_text);

std::optional<std::string> check_zone_bundle(const v1::ZoneBundle& bundle,
                                             std::string_view features_path);

nlohmann::json geojson_from_zone_bundle(const v1::ZoneBundle& bundle);

}  // namespace fleetgw::convert
