// GBFS v3.0 feeds (MobilityData's General Bikeshare Feed Specification) built from the registry
// and the ingest's tables; served under /gbfs/ by registry_routes.cc. docs/standards.md maps
// every field to its source.
//
// Contract:
//  * Each *_data() returns the feed's `data` object; gbfs_document() wraps it with
//    last_updated (RFC 3339, UTC), ttl (seconds) and version "3.0".
//  * Only registered vehicles (registry_vehicles, not removed) with a position appear, and never
//    one whose latest state is riding (an active rental).
//  * vehicle_id is random (gbfs_public_ids), never the vehicle's own id: it is replaced the
//    first time the feed is built after a trip began (the state showed riding at a build, or a
//    ride record with a later start than the id arrived) and is stable otherwise.
//    Listing order is by that random id. A ride shorter than the time between two builds and
//    whose record has not arrived yet shows the old id at the new place until it arrives.
//  * is_disabled: an active alarm, an active critical fault, SOC below low_battery_pct, or no
//    report for offline_after_s or an offline retained status. is_reserved: an operator's
//    reservation in force (registry_reservations.h); a reserved vehicle is still listed.
//  * current_range_meters: SOC x the type's capacity / the bike's measured energy per km (its
//    last 20 rides with energy and distance, at least 1 km in all); else the state's range_m;
//    else SOC x the type's max range. current_fuel_percent: SOC / 100 (GBFS: 0 to 1).
//  * geofencing_zones: the fleet-wide zone bundle with the highest version in zone_bundles
//    (gbfs_zones.cc); none: an empty FeatureCollection and no global rules.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/registry_options.h"

namespace fleetgw::web {

struct GbfsFeed {
  std::string_view name;
  int ttl_s;
};
// Every feed this server publishes, in discovery order.
inline constexpr GbfsFeed kGbfsFeeds[] = {{"gbfs", 300},
                                          {"system_information", 3600},
                                          {"vehicle_types", 300},
                                          {"vehicle_status", 15},
                                          {"geofencing_zones", 60}};

std::string rfc3339(std::int64_t us);
nlohmann::json gbfs_document(const nlohmann::json& data, int ttl_s, std::int64_t now_us);

nlohmann::json gbfs_discovery_data(std::string_view base_url);
nlohmann::json gbfs_system_information_data(const StandardsOptions& o);
nlohmann::json gbfs_vehicle_types_data(PgConnection& c, const StandardsOptions& o);
nlohmann::json gbfs_vehicle_status_data(PgConnection& c, const StandardsOptions& o,
                                        std::int64_t now_us);
// gbfs_zones.cc: the bundle in force, and any serialized ZoneBundle, as GBFS geofencing_zones
// data (throws std::invalid_argument when the bytes are not a bundle).
nlohmann::json gbfs_geofencing_zones_data(PgConnection& c, const StandardsOptions& o);
nlohmann::json gbfs_zones_from_bundle(std::string_view bundle_bytes, const StandardsOptions& o);

}  // namespace fleetgw::web
