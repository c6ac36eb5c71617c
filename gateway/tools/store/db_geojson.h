// `fleetgw db export --table rides --format geojson`: the rides as a GeoJSON FeatureCollection
// (RFC 7946) that any map tool opens (QGIS, geojson.io, ogr2ogr).
//
// Contract:
//  * One Feature per ride row (at or after `since_us`, in insertion order), `id` its ride_id.
//    geometry: a LineString of the ride's simplified track (`rides.track`, storage/track_text.h;
//    [longitude, latitude], WGS-84) when it has two or more positions, a Point when it has one
//    (a ride whose fixes never moved 5 m), null when the ride had no fix (a valid Feature).
//  * properties: ride_id, start and end (ISO 8601 UTC, end null while open), then every other
//    column of the row as `export --format jsonl` prints it (start_us, end_us, duration_s,
//    distance_km, gnss_distance_m, start_lat_deg ... assist_time_json as an object), except the
//    track itself and the store's row id.
//  * A stored track that is not valid (a damaged or edited file) gives geometry null and one
//    line on `err` naming the ride and the problem; the export goes on.
//  * Streamed: one Feature per line between the collection's first and last line, so days of
//    rides are never held in memory. Strings that are not UTF-8 are replaced, never emitted.
//  * geojson_tables() names the tables this format supports (rides only: other tables have no
//    geometry); the CLI refuses any other one with exit 2 before opening the store.
#pragma once

#include <array>
#include <cstdint>
#include <ostream>
#include <span>
#include <string_view>

#include "storage/store.h"

namespace fleetgw::tools {

inline constexpr std::array<std::string_view, 1> kGeojsonTables = {"rides"};

// Returns the number of Features written.
std::uint64_t export_rides_geojson(storage::Store& store, std::int64_t since_us, std::ostream& out,
                                   std::ostream& err);

}  // namespace fleetgw::tools
