// The fault-code table (spec §4 and the fault-word sections of §3): every fault bit of MC, BMS,
// OBC, IOT, locks (and the V3.0 HMI) with its display code where one exists, an English name and
// a severity. Bits are given in the *normalised* 32-bit word: high 16 bits = the documented high
// group, low 16 bits = the documented low group (decode() normalises per FaultWordLayout).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace motinova {

enum class FaultSource : uint8_t { kMc, kBms, kObc, kIot, kLock, kHmi };
std::string_view fault_source_name(FaultSource s);  // "mc", "bms", "obc", "iot", "lock", "hmi"

enum class Severity : uint8_t {
  kInfo,      // informational / reserved bit
  kWarning,   // degraded, ride can continue
  kCritical,  // protection tripped or hardware fault: assist stops or the pack is cut off
};
std::string_view severity_name(Severity s);  // "info", "warning", "critical"

struct FaultDef {
  FaultSource source;
  uint32_t mask;          // single bit in the normalised word
  int code;               // display code of §4, or -1 where the spec defines none
  std::string_view name;  // stable snake_case identifier, e.g. "over_current_protect"
  std::string_view text;  // English name as printed, e.g. "Over Current Protect"
  Severity severity;
  bool uncertain;  // [G] reading (U6, U18, U20, U22): name table may be overridden
};

// All defined bits of one source, in bit order.
std::span<const FaultDef> fault_table(FaultSource source);

// Definition of one bit, or nullptr when the bit is not defined (the caller then reports it as
// "undefined_bit_N" with severity warning: an unexpected bit is never silently dropped).
const FaultDef* find_fault(FaultSource source, uint32_t mask);

// Calls fn(mask, const FaultDef* def_or_null) for every set bit of `word`, low bit first.
template <typename Fn>
void for_each_active_fault(FaultSource source, uint32_t word, Fn&& fn) {
  for (unsigned bit = 0; bit < 32; ++bit) {
    const uint32_t mask = uint32_t{1} << bit;
    if (word & mask) fn(mask, find_fault(source, mask));
  }
}

}  // namespace motinova
