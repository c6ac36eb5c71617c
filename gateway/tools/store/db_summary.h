// `fleetgw db summary`: what the store says happened, in one sentence an operator can read
// ("1 ride, 8.1 km, 28 min; 1 fault raised, 1 cleared; 3 commands: 2 succeeded, 1 refused
// (interlock_moving); 1 alarm (theft)"), and the same counts for scripts.
//
// Contract:
//  * summarize() counts the rows of the four listings of Store::list_recent (rides, faults,
//    commands, alarms), all of them at or after `since_us` by the listings' own time columns:
//      rides     every ride row (open ones too, counted apart), their distance (odometer when
//                the ride has odometer readings, else integrated speed, as `db rides`),
//                duration, moving time and energy;
//      faults    fault events by `event`: raised, cleared, unknown; raised ones per "node:name";
//      commands  one per row of the listing (a result, or a journal entry still without one),
//                by result (succeeded, failed, timeout, rejected; a row without a result by its
//                journal state, e.g. executing); rejected ("refused") and failed/timeout ones
//                also by the code of their reason (the text before the first ':', as in
//                "interlock_moving: will not lock ..."; "unspecified" when empty);
//      alarms    raised transitions per kind, cleared transitions counted.
//    Missing or mistyped columns count as absent values; summarize() never throws.
//  * summary_sentence(): one line, counts first, plain words: "no rides" / "1 ride, 8.1 km,
//    28 min" (" (1 open)" when some are open); "no faults" / "N fault(s) raised, M cleared";
//    "no commands" / "N command(s): A succeeded, B refused (reasons), C failed, D timed out, E
//    executing" (only the non-zero parts, in that order; a single reason is named alone,
//    several as "2 interlock_moving, 1 expired"); "no alarms" / "N alarm(s) (theft)" with the
//    kinds in words (unauthorised_movement: theft, lock_forced: forced lock, low_battery: low
//    battery, battery_removed: battery removed, battery_swapped: battery swapped; other kinds by
//    name). The sentence is made printable as a whole (table_cell): reasons and kinds come
//    from the store and are untrusted.
//  * summary_json(): {"since": ISO 8601 | null, "summary": sentence, "rides": {...},
//    "faults": {...}, "commands": {...}, "alarms": {...}} (keys in db_summary.cc, documented in
//    docs/storage.md); summary_table(): one row per area (what, count, detail).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "gateway/tools/common/table_format.h"

namespace fleetgw::tools {

struct DbSummary {
  std::optional<std::int64_t> since_us;  // nullopt: the whole store

  std::uint64_t rides = 0;
  std::uint64_t rides_open = 0;
  std::uint64_t rides_partial = 0;
  double distance_km = 0;
  double duration_s = 0;
  double moving_s = 0;
  double energy_wh = 0;

  std::uint64_t faults_raised = 0;
  std::uint64_t faults_cleared = 0;
  std::uint64_t faults_unknown = 0;
  std::map<std::string, std::uint64_t> raised_by_fault;  // "mc:over_heat_protect" -> raised

  std::uint64_t commands = 0;
  std::map<std::string, std::uint64_t> commands_by_result;  // succeeded, rejected, executing...
  std::map<std::string, std::uint64_t> refused_by_reason;   // result "rejected"
  std::map<std::string, std::uint64_t> failed_by_reason;    // result "failed" or "timeout"

  std::uint64_t alarms_raised = 0;
  std::uint64_t alarms_cleared = 0;
  std::map<std::string, std::uint64_t> alarms_by_kind;  // raised transitions
};

// Rows as Store::list_recent returns them, per listing.
struct SummaryRows {
  std::vector<nlohmann::json> rides, faults, commands, alarms;
};

DbSummary summarize(const SummaryRows& rows, std::optional<std::int64_t> since_us);
std::string summary_sentence(const DbSummary& s);
nlohmann::json summary_json(const DbSummary& s);
Table summary_table(const DbSummary& s);

}  // namespace fleetgw::tools
