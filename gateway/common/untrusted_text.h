// Untrusted text: strings that arrived from the network (MQTT payload fields, key ids, vehicle
// ids, lock kinds...) are data, not text we wrote. Before such a string goes into a log line, a
// stored reason or a published message, it passes through here.
//
// Contract:
//  * Every function returns valid UTF-8, whatever the input bytes: an invalid or truncated
//    sequence becomes U+FFFD; nothing is ever cut inside a code point.
//  * truncate_utf8(s, max) returns the longest prefix of `s` of at most `max` bytes that ends on
//    a code-point boundary (valid UTF-8 input assumed for the "prefix" promise; invalid input is
//    repaired first, see above).
//  * escape_controls(s) makes a string one printable log line: C0 controls (including CR, LF,
//    TAB, ESC), DEL, the C1 controls U+0080..U+009F and the line/paragraph separators
//    U+2028/U+2029 become `\n`, `\r`, `\t` or `\xNN` / `\u{NNNN}`; a backslash becomes `\\`, so
//    the escaped text is unambiguous (a received "\n" cannot pass for an escaped newline).
//  * untrusted_excerpt(s, max) = escape then cut to at most `max` bytes on an escape/code-point
//    boundary, with "..." appended (within `max`) when something was cut. The form to use for
//    received strings quoted in logs and reasons.
//  * Pure functions, no allocation beyond the returned string, no locale.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace fleetgw::common {

// `s` with every invalid UTF-8 sequence replaced by U+FFFD.
std::string valid_utf8(std::string_view s);

// True when `s` is well-formed UTF-8 (no overlongs, no surrogates, nothing above U+10FFFF).
bool is_valid_utf8(std::string_view s);

std::string truncate_utf8(std::string_view s, std::size_t max_bytes);

std::string escape_controls(std::string_view s);

std::string untrusted_excerpt(std::string_view s, std::size_t max_bytes = 64);

}  // namespace fleetgw::common
