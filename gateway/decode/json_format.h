// JSON rendering of decoded MOTINOVA messages and reassembly errors: the output format of
// `fleetgw decode` (one object per line) and of anything else that shows bus traffic.
//
// Contract: the append_* functions write one compact JSON object (no newline) at the end of
// `out` without building an intermediate JSON tree: after the first few messages nothing is
// allocated per message. Output is valid JSON: strings are escaped (", \, control characters),
// and bytes outside ASCII, which only untrusted bus text can carry, are written as \u00XX.
// Field names are the product vocabulary of the catalogue; values are scaled to the unit in
// their name; invalid values (the spec's 0xFF/0xFFFF sentinels) are null. Numbers are printed as
// nlohmann::json prints them (integers plain, doubles shortest round-trip with ".0" when whole).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "motinova/codec.h"
#include "motinova/options.h"
#include "motinova/reassembler.h"

namespace fleetgw::decode {

// {"ts", "can_id", "src", "dst", "mode", "function", "message", ["mode_mismatch",] "fields"}.
void append_message_json(std::string& out, const motinova::DecodedMessage& message,
                         motinova::Micros ts, const motinova::DecodeOptions& options);

// Only the "fields" object.
void append_fields_json(std::string& out, const motinova::DecodedMessage& message,
                        const motinova::DecodeOptions& options);

// {"ts", "can_id", "error", "bytes_dropped"}.
void append_error_json(std::string& out, const motinova::ReassemblyErrorEvent& error);

// A JSON string literal (with quotes) of untrusted text.
void append_json_string(std::string& out, std::string_view text);

// A double as nlohmann::json dumps it ("25.3", "1700000000.0", "1e-05").
void append_json_double(std::string& out, double value);

// Lock kind fitted at a lock node per options (U21), or "" when `node` is not a lock.
std::string lock_kind(motinova::Node node, const motinova::DecodeOptions& options);

// "0x710"-style hex.
std::string hex_id(uint32_t value, int digits = 3);

}  // namespace fleetgw::decode
