// Received strings made safe to quote: the backend's own small copy of the rule the gateway
// applies to untrusted text (the backend depends on proto/ only, never on gateway/).
//
// Contract:
//  * is_valid_utf8(s): well-formed UTF-8 (no overlongs, no surrogates, nothing above U+10FFFF).
//  * truncate_utf8(s, max): the longest prefix of at most `max` bytes ending on a code-point
//    boundary; invalid sequences become U+FFFD first.
//  * untrusted_excerpt(s, max): one printable line of at most `max` bytes: controls, DEL and a
//    backslash escaped (`\n`, `\\`, `\xNN`), invalid bytes as U+FFFD, "..." when cut.
//  * Pure functions, no locale.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace fleetgw::ingest {

bool is_valid_utf8(std::string_view s);
std::string truncate_utf8(std::string_view s, std::size_t max_bytes);
std::string untrusted_excerpt(std::string_view s, std::size_t max_bytes = 64);

}  // namespace fleetgw::ingest
