// The text form of a ride's track in the store (`rides.track`, schema v6): a JSON array of
// [longitude, latitude] positions in WGS-84 degrees, in the ride's order, e.g.
// `[[13.405,52.52],[13.405,52.5209],[13.4071,52.5209]]`.
//
// Why this form: it is GeoJSON's own coordinate order and syntax (RFC 7946 §3.1.1), so
// `fleetgw db export --format geojson` and any SQLite user (`json_array_length(track)`,
// `json_extract(track, '$[0]')`) read it without a decoder; at 1e-7 degrees (the precision of
// the wire's Track, 1 cm) it costs about 24 bytes per vertex, small next to telemetry.
//
// Contract:
//  * track_text(points) writes each coordinate rounded to 1e-7 degrees, as the shortest
//    decimal of that value (no exponent, no trailing zeros). An empty span gives "[]".
//  * parse_track_text(text) accepts exactly that shape: a JSON array whose every element is an
//    array of two finite numbers, longitude in -180..180 and latitude in -90..90. Anything else
//    (not JSON, another shape, a value out of range) returns an error naming the position index
//    and what is wrong; it never throws. The stored text is not trusted: a file may have been
//    edited or damaged.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::storage {

struct TrackPoint {
  double lat_deg = 0;
  double lon_deg = 0;
  friend bool operator==(const TrackPoint&, const TrackPoint&) = default;
};

std::string track_text(std::span<const TrackPoint> points);

struct ParsedTrack {
  std::vector<TrackPoint> points;
  std::string error;  // empty when the text is a valid track
  bool ok() const { return error.empty(); }
};
ParsedTrack parse_track_text(std::string_view text);

}  // namespace fleetgw::storage
