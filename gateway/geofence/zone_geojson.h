// Zones drawn on a map: a GeoJSON FeatureCollection (RFC 7946, what geojson.io and QGIS write)
// turned into a fleetgw.v1.ZoneBundle for `fleetgw zones sign`. Pure: text in, bundle out.
//
// Contract:
//  * Each Feature is one zone: geometry Polygon (its rings: the boundary, then holes) or
//    MultiPolygon (every ring of every polygon, under the even-odd rule: polygons must not
//    overlap); properties "id" (or the Feature's "id"), "kind" ("operating_area", "slow",
//    "no_ride", "no_parking", "no_start" since issue 27), "name" (optional), "speed_limit_kmh"
//    (slow zones). A GBFS geofencing_zones.json goes through proto/convert/gbfs_zones.h instead.
//  * Positions are [longitude, latitude] in degrees (GeoJSON order), rounded to 1e-7 degrees;
//    a closing position equal to the first is kept (the bundle accepts it).
//  * Anything that is not such a collection -- not JSON, a missing or mistyped member, a
//    coordinate that is not a finite number in range -- is refused with a message naming the
//    feature (index and id), the ring and the position. The zone rules themselves (at least 3
//    distinct vertices, ids, limits...) are compile_zones()'s: bundle_from_geojson() runs it on
//    the result, so a bundle it returns is one a gateway accepts.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <variant>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_engine.h"

namespace fleetgw::geofence {

std::variant<v1::ZoneBundle, std::string> bundle_from_geojson(std::string_view text,
                                                              std::uint64_t version,
                                                              Micros issued_at);

}  // namespace fleetgw::geofence
