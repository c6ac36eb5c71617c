// Fault-bit naming with the configurable readings U6 (MC), U18 (IOT), U20 (locks) and U22 (BMS
// group B) applied on top of the fault table of faults.h.
//
// Contract: pure lookups, no allocation. A returned FaultDef's name/text may view strings of the
// DecodeOptions, which must outlive it. Without overrides the answer is find_fault()'s.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "motinova/faults.h"
#include "motinova/options.h"

namespace motinova {

// Definition of one bit under `options`, or nullopt when the bit is not defined.
std::optional<FaultDef> describe_fault(FaultSource source, uint32_t mask,
                                       const DecodeOptions& options);
// The same with only the name overrides (for holders of DecodeOptions::fault_names alone).
std::optional<FaultDef> describe_fault(FaultSource source, uint32_t mask,
                                       std::span<const FaultNameOverride> overrides);

// Calls fn(mask, const FaultDef* def_or_null) for every set bit of `word`, low bit first.
template <typename Fn>
void for_each_active_fault(FaultSource source, uint32_t word, const DecodeOptions& options,
                           Fn&& fn) {
  for (unsigned bit = 0; bit < 32; ++bit) {
    const uint32_t mask = uint32_t{1} << bit;
    if (!(word & mask)) continue;
    const std::optional<FaultDef> def = describe_fault(source, mask, options);
    fn(mask, def ? &*def : nullptr);
  }
}

// Parses a fault-bit key of the config and flags: "0x0080" or "low_0x0080" (low group),
// "high_0x0002" (documented high group), or a normalised 32-bit "0x00020000". nullopt unless the
// key names exactly one bit.
std::optional<uint32_t> parse_fault_bit(std::string_view key);

}  // namespace motinova
