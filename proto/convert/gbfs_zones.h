// GBFS v3.0 geofencing_zones.json <-> fleetgw.v1.ZoneBundle (issue 27): the pure conversion
// shared by the bike's operator tool (`fleetgw zones sign|export`, gateway/geofence/) and the
// backend (`fleetgw serve`'s /gbfs/geofencing_zones.json, the console's zones page). It depends
// on proto/ (fleetgw_proto) and nlohmann-json only: no gateway code, no I/O, no clock, no
// signing (a bundle it returns still has to be versioned, signed and judged by the caller).
//
// API
//  * zone_bundle_from_gbfs(text) reads a GBFS v3.0 geofencing_zones.json as published (the
//    whole document: last_updated, ttl, version, data.geofencing_zones, data.global_rules) and
//    returns the ZoneBundle's zones and rules -- precedence FIRST_MATCH, one zone of kind
//    ZONE_KIND_RULES per Feature in the file's order (id "gbfs-<index>", or the Feature's own
//    string "id" when it is a valid zone id), its MultiPolygon's rings with `polygon_rings`,
//    `names` and `name` (the first text, cut to 128 bytes at a character boundary), start/end
//    (RFC 3339, any offset) as start_us/end_us, every rule as a ZoneRule, global_rules as
//    default_rules -- plus `notes`: what was read but has no effect on the bike, each with its
//    JSON path (an unknown member of the document, of data or of a Feature's properties; a
//    station_parking of false; a Polygon where v3.0 says MultiPolygon). version, issued_at_us
//    and vehicle_id are left at 0/empty for the caller.
//    Refused (the returned string names the rule and its place as a JSON path, e.g.
//    `data.geofencing_zones.features[3].properties.rules[0].station_parking: true is not
//    enforced by the bike (it knows no stations); refusing rather than dropping the rule`):
//    not JSON, a `version` other than "3.0", a missing or mistyped member, a rule with
//    station_parking true or any member this mapping does not know (a restriction the bike
//    cannot enforce is never dropped), a maximum_speed_kph that is not a whole number in
//    0..255, a position that is not [longitude, latitude] in range, a start/end that is not
//    RFC 3339 or an end not after its start. The geometry rules themselves (3 distinct
//    vertices, ...) are the gateway's compile_zones(): a caller signs only what it accepts.
//  * gbfs_from_zone_bundle(bundle, options) writes a bundle back as a GBFS v3.0
//    geofencing_zones.json document (nlohmann::json; dump() it). A FIRST_MATCH bundle of RULES
//    zones (what zone_bundle_from_gbfs made) comes back with the same features in the same
//    order, the same rules, names, windows and coordinates (1e-7 degrees; a ring closed as
//    GBFS requires) and the same global_rules. Rings follow GBFS's right-hand rule: a
//    polygon's exterior ring counter-clockwise, its holes clockwise (without polygon grouping,
//    a ring inside an odd number of the zone's other rings is a hole); a ring the other way
//    round is written reversed from the same first vertex -- the same area to the bike, which
//    reads rings by even-odd. So from_gbfs(to_gbfs(b)) == b for every bundle from_gbfs returns
//    from a right-hand document (its document comes back unchanged), and a left-hand
//    document's rings come back reversed. A bundle of the older kinds (from GeoJSON, precedence
//    UNION) is written as the rules the bike enforces, one feature per zone: slow ->
//    maximum_speed_kph, no_ride -> ride_through_allowed false, no_parking -> ride_end_allowed
//    false, no_start -> ride_start_allowed false, operating_area -> every ride allowed inside; with
//    operating areas, global_rules say rides may neither start nor end outside them. Under UNION
//    the features are ordered most restrictive first (no-ride, slow by rising limit, no-parking,
//    no-start, areas), which gives GBFS's first-match reading the bike's meaning wherever
//    zones of one kind overlap; where zones of different kinds overlap GBFS cannot say "both"
//    and the first feature's rule is what a GBFS reader sees (docs/location.md).
//    last_updated is options.last_updated_us, or the bundle's issued_at_us when 0; ttl is
//    options.ttl_s.
//  * rfc3339_from_us() / us_from_rfc3339(): the timestamps' form (UTC, "Z", microseconds only
//    when not whole seconds), shared by the feeds.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "fleetgw/v1/zones.pb.h"

namespace fleetgw::convert {

struct GbfsZonesImport {
  v1::ZoneBundle bundle;
  // Read but without effect on the bike, each "<json path>: <what>" (reported, never silent).
  std::vector<std::string> notes;
};

std::variant<GbfsZonesImport, std::string> zone_bundle_from_gbfs(std::string_view json_text);

// True when `json_text` is a JSON object with data.geofencing_zones (a GBFS geofencing_zones
// document), false for anything else (e.g. a plain GeoJSON FeatureCollection).
bool is_gbfs_geofencing_zones(std::string_view json_text);

struct GbfsExportOptions {
  std::int64_t last_updated_us = 0;  // 0: the bundle's issued_at_us
  std::uint32_t ttl_s = 0;
};

nlohmann::json gbfs_from_zone_bundle(const v1::ZoneBundle& bundle,
                                     const GbfsExportOptions& options = {});

std::string rfc3339_from_us(std::int64_t us);
std::optional<std::int64_t> us_from_rfc3339(std::string_view text);

}  // namespace fleetgw::convert
