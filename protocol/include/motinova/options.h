// Runtime options for the readings of the spec that are uncertain (spec §6). Every default is
// the spec's documented best guess; the gateway's config file can override each one.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "motinova/bytes.h"
#include "motinova/faults.h"
#include "motinova/frame.h"

namespace motinova {

// U3: how a 4-byte fault word is laid out on the wire.
enum class FaultWordLayout : uint8_t {
  kDocumented,       // one uint32 in data byte order; groups as documented in §3 (best guess)
  kSwappedGroups,    // one uint32, but the documented high and low 16-bit groups swapped
  kTwoWordsLowFirst  // two independent 16-bit words (data byte order), low word sent first
};

// U9: order of the MC 0x1020 voltage (offset 6) and current (offset 8) fields.
enum class McVoltageCurrentOrder : uint8_t {
  kVoltageFirst,  // V3.0 layout (best guess)
  kCurrentFirst,  // V4.6.2 OCR hint
  kAuto           // the one within 20 000..60 000 mV is the voltage
};

// U14: the ID on which the MC answers the IOT's reads (0x3300, 0x3900, 0x4300, 0x3500).
enum class McAnswerId : uint8_t {
  k713,  // MC -> OBC, as for the OBC (best guess)
  k716,  // MC -> IOT
  k710,  // MC broadcast
  kAuto  // accept the answers on any of the three (the bus settles it)
};

// U11: what byte 0 of the MC settings (0x5408, V3.0 0x7308) counts. Decoded always as the
// wheel circumference in cm ("wheel_size_cm").
enum class WheelSizeUnit : uint8_t {
  kCircumferenceCm,  // best guess
  kDiameterCm,
  kDiameterInch
};

// U11: unit of the signed wheel-adjust byte; decoded always in cm ("wheel_adjust_cm").
enum class WheelAdjustUnit : uint8_t { kCm, kMm };

// U17: pack-statistics (0x725/0x5028) readings.
inline constexpr std::size_t kPackStatsCounters = 9;
inline constexpr std::array<std::string_view, kPackStatsCounters> kPackStatsCounterNames{
    "over_charge_count",         "over_discharge_count",
    "charge_over_current_count", "discharge_over_current_count",
    "short_circuit_count",       "charge_over_temp_count",
    "charge_under_temp_count",   "discharge_over_temp_count",
    "discharge_under_temp_count"};
enum class PackTimeUnit : uint8_t { kHours, kMinutes };

// U6, U18, U20, U22: the name of one fault bit. When `name` is the name of another bit of the
// same source in the fault table, that bit's code and severity move along with the name (the
// spec's alternative is a permutation of the documented codes); otherwise the bit gets `name`,
// no code and severity warning.
struct FaultNameOverride {
  FaultSource source = FaultSource::kMc;
  uint32_t mask = 0;  // single bit of the normalised word (documented high group << 16)
  std::string name;
};

struct DecodeOptions {
  CrcOrder crc_order = CrcOrder::kBig;     // U1 (used by the reassembler / encoder)
  ByteOrder data_order = ByteOrder::kBig;  // U2

  FaultWordLayout mc_fault_layout = FaultWordLayout::kDocumented;     // U3
  FaultWordLayout bms_fault_layout = FaultWordLayout::kDocumented;    // U3
  FaultWordLayout other_fault_layout = FaultWordLayout::kDocumented;  // U3: OBC, IOT, locks

  bool bms_current_charge_positive = true;  // U4: BMS 0x1010 current, charge = + (best guess)
  bool mc_current_signed = false;           // U4: MC 0x1020 current as s16
  McVoltageCurrentOrder mc_voltage_current_order = McVoltageCurrentOrder::kVoltageFirst;  // U9

  // U19: names of lock-state values 0..6.
  std::array<std::string, 7> lock_state_names{"unknown", "unlocked",      "locked",     "unlocking",
                                              "locking", "unlock_failed", "lock_failed"};
  // U21: lock kind fitted at lock node 7..B (LOCK 1..5). Empty = not fitted.
  std::array<std::string, 5> lock_kinds{"seat", "frame", "steering", "battery", "other"};

  McAnswerId mc_answer_id = McAnswerId::k713;                       // U14
  WheelSizeUnit wheel_size_unit = WheelSizeUnit::kCircumferenceCm;  // U11
  WheelAdjustUnit wheel_adjust_unit = WheelAdjustUnit::kCm;         // U11

  // U17: offset 2 is the maximum discharge current and offset 4 the maximum charge current
  // (best guess); false swaps them.
  bool pack_stats_discharge_current_first = true;
  PackTimeUnit pack_stats_time_unit = PackTimeUnit::kHours;  // U17: offsets 8/10
  // U17: the counter at offset 12 + 2 i is pack_stats_counter_order[i] (a permutation of
  // kPackStatsCounterNames; default = the alarm-bit order).
  std::array<std::string, kPackStatsCounters> pack_stats_counter_order{
      std::string(kPackStatsCounterNames[0]), std::string(kPackStatsCounterNames[1]),
      std::string(kPackStatsCounterNames[2]), std::string(kPackStatsCounterNames[3]),
      std::string(kPackStatsCounterNames[4]), std::string(kPackStatsCounterNames[5]),
      std::string(kPackStatsCounterNames[6]), std::string(kPackStatsCounterNames[7]),
      std::string(kPackStatsCounterNames[8])};

  // U6 (MC), U18 (IOT), U20 (locks), U22 (BMS group B): fault-bit names replacing the table's.
  std::vector<FaultNameOverride> fault_names;

  // U7: assist-level names; values not listed here decode as "0xNN".
  struct AssistName {
    uint8_t value;
    std::string name;
  };
  std::vector<AssistName> assist_names{{0x00, "off"},       {0x01, "eco"},   {0x02, "norm"},
                                       {0x03, "sport"},     {0x04, "turbo"}, {0x05, "walk"},
                                       {0x11, "eco2"},      {0x12, "norm2"}, {0x13, "sport2"},
                                       {0x14, "turbo2"},    {0x15, "walk2"}, {0x22, "special_22"},
                                       {0x33, "special_33"}};
};

}  // namespace motinova
