// MDS 2.0 Policy (speed rules) + Geography -> fleetgw.v1.ZoneBundle (issue 27): a city's speed
// limits as published for the Mobility Data Specification, on the same footing as GBFS
// (gbfs_zones.h). Pure, on proto/ and nlohmann-json only.
//
// API
//  * zone_bundle_from_mds(policy_text, geography_text) reads an MDS Policy document (policies
//    under "data.policies", or "policies", or one "policy") and the Geography document its
//    rules name (under "data.geographies", "geographies" or one "geography"; each geography's
//    "geography_json" a GeoJSON FeatureCollection, a Feature or a geometry of Polygons or
//    MultiPolygons) and returns the bundle's zones: precedence FIRST_MATCH (an MDS vehicle is
//    matched by the first rule that applies to it), one zone of kind RULES per (rule,
//    geography) in the policy's order, id "mds-<policy>-<rule>-<geography>" (indexes), name
//    "<rule name> / <geography name>" (cut to 128 bytes), one ZoneRule allowing every ride with
//    maximum_speed_kph = the rule's maximum (mph converted and rounded down: the bike never
//    gets more than the city allows), start_us/end_us = the policy's start_date/end_date
//    (milliseconds since the epoch; end null: no end). Notes (JSON path: what) for what has no
//    effect on the bike: messages, a rule's states (the limit is enforced in every state: a
//    parked bike does not move), unknown members outside rules, a rule whose vehicle_types
//    leave out "bicycle" (not for these bikes: skipped).
//    Refused, naming the rule and its JSON path: a rule_type other than "speed" (count, time,
//    rate and user rules need a fleet or a rider, not a bike), days / start_time / end_time
//    (a weekly schedule: the bundle's windows are one interval), a minimum, rule_units other
//    than "kph" or "mph", a maximum that is not a number in 0..255 km/h after conversion, a
//    geography the Geography document lacks, any other member of a rule.
#pragma once

#include <string>
#include <string_view>
#include <variant>

#include "proto/convert/gbfs_zones.h"

namespace fleetgw::convert {

std::variant<GbfsZonesImport, std::string> zone_bundle_from_mds(std::string_view policy_text,
                                                                std::string_view geography_text);

}  // namespace fleetgw::convert
