// JSON rendering of decoded MOTINOVA messages and reassembly errors: the output format of
// `fleetgw decode` (one object per line) and of anything else that shows bus traffic.
//
// Contract: pure functions; field names are the product vocabulary of the catalogue; values are
// scaled to the unit in their name; invalid values (the spec's 0xFF/0xFFFF sentinels) are null.
#pragma once

#include <nlohmann/json.hpp>

#include "motinova/codec.h"
#include "motinova/options.h"
#include "motinova/reassembler.h"

namespace fleetgw::decode {

// {"ts", "can_id", "src", "dst", "mode", "function", "message", "fields"}.
nlohmann::ordered_json message_to_json(const motinova::DecodedMessage& message, motinova::Micros ts,
                                       const motinova::DecodeOptions& options);

// Only the "fields" object.
nlohmann::ordered_json fields_to_json(const motinova::DecodedMessage& message,
                                      const motinova::DecodeOptions& options);

// {"ts", "can_id", "error", "bytes_dropped"}.
nlohmann::ordered_json error_to_json(const motinova::ReassemblyErrorEvent& error);

// Lock kind fitted at a lock node per options (U21), or "" when `node` is not a lock.
std::string lock_kind(motinova::Node node, const motinova::DecodeOptions& options);

// "0x710"-style hex.
std::string hex_id(uint32_t value, int digits = 3);

}  // namespace fleetgw::decode
