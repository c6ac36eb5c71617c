// Runtime options for the readings of the spec that are uncertain (spec §6). Every default is
// the spec's documented best guess; the gateway's config file can override each one.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "motinova/bytes.h"
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

  // U7: assist-level names; values not listed here decode as "0xNN".
  struct AssistName {
    uint8_t value;
    std::string name;
  };
  std::array<AssistName, 13> assist_names{{{0x00, "off"},
                                           {0x01, "eco"},
                                           {0x02, "norm"},
                                           {0x03, "sport"},
                                           {0x04, "turbo"},
                                           {0x05, "walk"},
                                           {0x11, "eco2"},
                                           {0x12, "norm2"},
                                           {0x13, "sport2"},
                                           {0x14, "turbo2"},
                                           {0x15, "walk2"},
                                           {0x22, "special_22"},
                                           {0x33, "special_33"}}};
};

}  // namespace motinova
