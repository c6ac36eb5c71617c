// The vehicle page's ride plot and the speed limit's reasons (issue 28), over the ingest's
// tables (rides, telemetry_samples, zone_events) and the console's own console_commands.
//
// Contract:
//  * ride_detail() is nullopt for an unknown (vehicle, ride); else {"vehicle_id", "ride": the
//    ride's summary as in vehicle()'s rides, "fields": ["t_us", "speed_kmh", "power_w",
//    "soc_pct", "lat", "lon"], "samples": [[...], ...] in time order, "samples_in_ride": N}.
//    The samples are the vehicle's telemetry between the ride's start and end (now while it
//    has no end), thinned to at most kMaxRideSamples by keeping every k-th, the last kept too.
//  * speed_limit() is {"in_force_kmh": what the MC reports (vehicle_state.speed_limit_dkmh)
//    or null, "operator_cap": the latest succeeded speed_limit command from the console (who,
//    when, the km/h asked, the bike's own one-line account `limit_in_force`) or null,
//    "slow_zones": the slow zones the bike last reported entering and not leaving (id, name,
//    km/h, since)}. Together they say why the limit in force is what it is: the MC is given
//    min(operator cap, slow zones, its own limit).
//  * Every string is untrusted data, going out only as JSON strings; every value a parameter.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string_view>

#include "backend/common/pg.h"

namespace fleetgw::web {

inline constexpr int kMaxRideSamples = 2000;

std::optional<nlohmann::json> ride_detail(PgConnection& c, std::string_view vehicle_id,
                                          std::string_view ride_id);
nlohmann::json speed_limit(PgConnection& c, std::string_view vehicle_id,
                           const nlohmann::json& reported);

}  // namespace fleetgw::web
