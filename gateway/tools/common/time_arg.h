// Times on the command line: the `--since` argument of the inspection commands and the UTC
// timestamps they print.
//
// Contract:
//  * parse_since(text, now_us) returns microseconds since the Unix epoch, or nullopt when `text`
//    is none of these forms (never throws):
//      - digits only: microseconds since the epoch, as before ("1763700000000000");
//      - relative, before `now_us`: digits and one unit, s m h d ("90s", "15m", "2h", "3d");
//      - ISO 8601 date: "2026-11-27" (00:00:00 UTC that day);
//      - ISO 8601 date and time: "2026-11-27T10:00:00Z", "T" (or "t", or one space) between,
//        seconds optional, fraction of a second optional (up to 6 digits), zone "Z", "+HH:MM",
//        "-HH:MM", "+HHMM" or none (none means UTC: these tools never use local time).
//    The calendar is checked (no 2026-02-30, no 24:00, no 10:60); values that overflow 64-bit
//    microseconds are refused.
//  * iso_utc(us) formats a time as "2026-11-27T10:00:00Z" (UTC, whole seconds, rounded down).
//  * kSinceForms names the accepted forms for error messages.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fleetgw::tools {

inline constexpr std::string_view kSinceForms =
    "an ISO 8601 UTC time (2026-11-27T10:00:00Z, or a date: 2026-11-27), a relative time "
    "(90s, 15m, 2h, 3d) or microseconds since the epoch";

std::optional<std::int64_t> parse_since(std::string_view text, std::int64_t now_us);

std::string iso_utc(std::int64_t us);

// The current wall clock in microseconds since the epoch (the CLI's `now`).
std::int64_t wall_clock_us();

}  // namespace fleetgw::tools
