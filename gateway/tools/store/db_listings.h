// `fleetgw db rides|faults|commands|alarms`: the rows of Store::list_recent() as a Table
// (table_format.h) in human units.
//
// Contract:
//  * listing_table(name, rows) builds the table of one listing from its rows, in the order
//    given (newest first as the store returns them). Times are ISO 8601 UTC strings
//    (time_arg.h), durations in minutes, distances in km, nodes by name (mc, bms, lock1...),
//    never raw numbers. Missing values stay null ("-" in the table, empty in CSV).
//  * Column keys (JSON members, CSV header) are snake_case with their unit:
//      rides:    ride_id start end state partial duration_min moving_min distance_km
//                avg_speed_kmh max_speed_kmh energy_wh soc_start_pct soc_end_pct faults
//      faults:   time node fault code severity event occurrences first_seen last_seen
//      commands: time command_id result reason final_state duration_ms
//      alarms:   time alarm transition lock speed_kmh soc_pct detail
//    distance_km is the odometer distance when the ride has odometer readings, else the
//    distance integrated from wheel speed; a command without a result shows its journal
//    state (e.g. executing) as its result.
//  * Unknown names throw std::invalid_argument.
#pragma once

#include <nlohmann/json.hpp>

#include <string_view>
#include <vector>

#include "gateway/tools/common/table_format.h"

namespace fleetgw::tools {

Table listing_table(std::string_view name, const std::vector<nlohmann::json>& rows);

}  // namespace fleetgw::tools
