// Values of the [protocol] options (the spec's uncertain readings, MOTINOVA-CAN.md section 6)
// as both the configuration file and the command-line flags spell them: one parser per option,
// so `fleetgw decode --crc-order` and `[protocol] crc_order` accept and refuse the same words.
#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <set>
#include <stdexcept>

#include "gateway/config/config.h"
#include "motinova/fault_names.h"

namespace fleetgw::config {

motinova::CrcOrder parse_crc_order(std::string_view s) {
  if (s == "be") return motinova::CrcOrder::kBig;
  if (s == "le") return motinova::CrcOrder::kLittle;
  if (s == "auto") return motinova::CrcOrder::kAuto;
  throw std::invalid_argument(fmt::format("crc order must be be, le or auto, got \"{}\"", s));
}

motinova::ByteOrder parse_byte_order(std::string_view s) {
  if (s == "be") return motinova::ByteOrder::kBig;
  if (s == "le") return motinova::ByteOrder::kLittle;
  throw std::invalid_argument(fmt::format("byte order must be be or le, got \"{}\"", s));
}

motinova::FaultWordLayout parse_fault_layout(std::string_view s) {
  if (s == "documented") return motinova::FaultWordLayout::kDocumented;
  if (s == "swapped") return motinova::FaultWordLayout::kSwappedGroups;
  if (s == "two_words_low_first") return motinova::FaultWordLayout::kTwoWordsLowFirst;
  throw std::invalid_argument(fmt::format(
      "fault layout must be documented, swapped or two_words_low_first, got \"{}\"", s));
}

motinova::McVoltageCurrentOrder parse_mc_vi_order(std::string_view s) {
  if (s == "voltage_first") return motinova::McVoltageCurrentOrder::kVoltageFirst;
  if (s == "current_first") return motinova::McVoltageCurrentOrder::kCurrentFirst;
  if (s == "auto") return motinova::McVoltageCurrentOrder::kAuto;
  throw std::invalid_argument(fmt::format(
      "MC voltage/current order must be voltage_first, current_first or auto, got \"{}\"", s));
}

motinova::McAnswerId parse_mc_answer_id(std::string_view s) {
  if (s == "0x713") return motinova::McAnswerId::k713;
  if (s == "0x716") return motinova::McAnswerId::k716;
  if (s == "0x710") return motinova::McAnswerId::k710;
  if (s == "auto") return motinova::McAnswerId::kAuto;
  throw std::invalid_argument(
      fmt::format("MC answer ID must be 0x713, 0x716, 0x710 or auto, got \"{}\"", s));
}

motinova::WheelSizeUnit parse_wheel_size_unit(std::string_view s) {
  if (s == "circumference_cm") return motinova::WheelSizeUnit::kCircumferenceCm;
  if (s == "diameter_cm") return motinova::WheelSizeUnit::kDiameterCm;
  if (s == "diameter_inch") return motinova::WheelSizeUnit::kDiameterInch;
  throw std::invalid_argument(fmt::format(
      "wheel size unit must be circumference_cm, diameter_cm or diameter_inch, got \"{}\"", s));
}

motinova::WheelAdjustUnit parse_wheel_adjust_unit(std::string_view s) {
  if (s == "cm") return motinova::WheelAdjustUnit::kCm;
  if (s == "mm") return motinova::WheelAdjustUnit::kMm;
  throw std::invalid_argument(fmt::format("wheel adjust unit must be cm or mm, got \"{}\"", s));
}

namespace {
// Names become JSON keys' values, log text and MQTT payloads: keep them plain identifiers.
bool plain_name(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    if (!ok) return false;
  }
  return true;
}
}  // namespace

std::string set_fault_name(motinova::DecodeOptions& p, motinova::FaultSource source,
                           std::string_view bit, std::string_view name) {
  const auto mask = motinova::parse_fault_bit(bit);
  if (!mask) {
    return fmt::format("\"{}\" is not one fault bit (e.g. low_0x0080, high_0x0002, 0x0080)", bit);
  }
  if (!plain_name(name)) {
    return fmt::format("fault name \"{}\" must be 1-64 characters of a-z, 0-9 and _", name);
  }
  for (auto& o : p.fault_names) {
    if (o.source == source && o.mask == *mask) {
      o.name = std::string(name);
      return "";
    }
  }
  p.fault_names.push_back({source, *mask, std::string(name)});
  return "";
}

std::string set_assist_name(motinova::DecodeOptions& p, std::string_view value,
                            std::string_view name) {
  unsigned v = 0;
  const bool hex = value.starts_with("0x") || value.starts_with("0X");
  const std::string_view digits = hex ? value.substr(2) : value;
  const auto [end, ec] =
      std::from_chars(digits.data(), digits.data() + digits.size(), v, hex ? 16 : 10);
  if (digits.empty() || ec != std::errc{} || end != digits.data() + digits.size() || v > 0xFF) {
    return fmt::format("assist level \"{}\" must be a byte value such as 0x33", value);
  }
  if (!plain_name(name)) {
    return fmt::format("assist name \"{}\" must be 1-64 characters of a-z, 0-9 and _", name);
  }
  for (auto& a : p.assist_names) {
    if (a.value == v) {
      a.name = std::string(name);
      return "";
    }
  }
  p.assist_names.push_back({static_cast<uint8_t>(v), std::string(name)});
  return "";
}

std::string set_pack_stats_counter_order(motinova::DecodeOptions& p,
                                         const std::vector<std::string>& names) {
  if (names.size() != motinova::kPackStatsCounters) {
    return fmt::format("expected the {} counter names", motinova::kPackStatsCounters);
  }
  std::set<std::string_view> seen;
  for (const auto& n : names) {
    const bool known =
        std::find(motinova::kPackStatsCounterNames.begin(), motinova::kPackStatsCounterNames.end(),
                  n) != motinova::kPackStatsCounterNames.end();
    if (!known || !seen.insert(n).second) {
      return fmt::format(
          "must name each of over_charge_count, over_discharge_count, charge_over_current_count, "
          "discharge_over_current_count, short_circuit_count, charge_over_temp_count, "
          "charge_under_temp_count, discharge_over_temp_count, discharge_under_temp_count once "
          "(\"{}\")",
          n);
    }
  }
  std::copy(names.begin(), names.end(), p.pack_stats_counter_order.begin());
  return "";
}

}  // namespace fleetgw::config
