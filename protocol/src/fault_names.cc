#include "motinova/fault_names.h"

#include <bit>
#include <charconv>

namespace motinova {

std::optional<FaultDef> describe_fault(FaultSource source, uint32_t mask,
                                       const DecodeOptions& options) {
  return describe_fault(source, mask, options.fault_names);
}

std::optional<FaultDef> describe_fault(FaultSource source, uint32_t mask,
                                       std::span<const FaultNameOverride> overrides) {
  for (const FaultNameOverride& o : overrides) {
    if (o.source != source || o.mask != mask) continue;
    // A name of the table moves with its code and severity (a permutation of §4's codes).
    for (const FaultDef& d : fault_table(source)) {
      if (d.name == o.name) {
        FaultDef moved = d;
        moved.mask = mask;
        moved.uncertain = true;
        return moved;
      }
    }
    return FaultDef{source, mask, -1, o.name, o.name, Severity::kWarning, true};
  }
  const FaultDef* def = find_fault(source, mask);
  return def ? std::optional<FaultDef>(*def) : std::nullopt;
}

std::optional<uint32_t> parse_fault_bit(std::string_view key) {
  int shift = 0;
  bool grouped = false;
  if (key.starts_with("high_")) {
    key.remove_prefix(5);
    shift = 16;
    grouped = true;
  } else if (key.starts_with("low_")) {
    key.remove_prefix(4);
    grouped = true;
  }
  if (!key.starts_with("0x") && !key.starts_with("0X")) return std::nullopt;
  key.remove_prefix(2);
  uint64_t value = 0;
  const auto [end, ec] = std::from_chars(key.data(), key.data() + key.size(), value, 16);
  if (ec != std::errc{} || end != key.data() + key.size()) return std::nullopt;
  if (value == 0 || !std::has_single_bit(value)) return std::nullopt;
  if (grouped ? value > 0xFFFF : value > 0xFFFFFFFFu) return std::nullopt;
  return static_cast<uint32_t>(value << shift);
}

}  // namespace motinova
