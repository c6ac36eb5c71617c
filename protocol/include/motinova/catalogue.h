// The declarative message catalogue (spec §3.1 for V4.6.2, plus the legible V3.0-only
// broadcasts of §5.2). One MessageDesc per (CAN ID, function code); one FieldDesc per field.
// A correction to the spec is meant to be a one-line change in catalogue_*.cc.
//
// Contract: the catalogue is immutable after construction and safe to share between threads.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "motinova/can.h"
#include "motinova/faults.h"
#include "motinova/frame.h"

namespace motinova {

enum class FieldKind : uint8_t {
  kUnsigned,   // unsigned integer of `size` bytes: value = raw * scale + bias
  kSigned,     // two's-complement integer of `size` bytes: value = raw * scale + bias
  kBool,       // true when (raw & bool_mask) != 0, or raw == true_raw when bool_mask == 0
  kEnum,       // raw value with a name from `enum_names` (or a configurable table, see Quirk)
  kFlags,      // bit-field exposed as its raw integer
  kAscii,      // fixed-length ASCII, space padded; decoded with trailing spaces/NULs removed
  kBytes,      // opaque bytes, exposed as hex
  kArray,      // `count` unsigned elements of `size` bytes each (e.g. 16 cell voltages)
  kFaultWord,  // 4-byte fault word, normalised per FaultWordLayout, bits named by faults.h
  kReserved,   // transmitted as 0x00, ignored on receive, not exposed
};

// Fields whose reading depends on an uncertain-reading option (spec §6).
enum class Quirk : uint8_t {
  kNone,
  kBmsCurrent,   // U4: sign convention of BMS pack current
  kMcCurrent,    // U4: MC bus current signed or not
  kMcVoltage,    // U9: MC voltage/current position
  kAssist,       // U7: assist-level names from DecodeOptions::assist_names
  kLockState,    // U19: lock-state names from DecodeOptions::lock_state_names
  kWheelSize,    // U11: wheel size unit (DecodeOptions::wheel_size_unit), decoded as cm
  kWheelAdjust,  // U11: wheel adjust unit (DecodeOptions::wheel_adjust_unit), decoded as cm
  kPackDischargeCurrent,  // U17: 0x5028 offset 2 (swapped with offset 4 when configured)
  kPackChargeCurrent,     // U17: 0x5028 offset 4
  kPackTime,              // U17: 0x5028 offsets 8/10 in hours or minutes, decoded as hours
  kPackCounter,           // U17: 0x5028 counters placed per pack_stats_counter_order
};

// How an enum appears in JSON: "assist": 2, "assist_name": "norm" (kRawThenName) or
// "state": "locked", "state_raw": 2 (kNameThenRaw).
enum class EnumStyle : uint8_t { kRawThenName, kNameThenRaw };

struct EnumEntry {
  int64_t value;
  std::string_view name;
};

struct FieldDesc {
  std::string_view name;  // product vocabulary, unit in the name: "speed_kmh", "voltage_v"
  uint8_t offset = 0;
  uint8_t size = 1;  // bytes (per element for kArray)
  FieldKind kind = FieldKind::kUnsigned;
  double scale = 1.0;
  double bias = 0.0;         // e.g. -40 for temperatures
  uint8_t count = 1;         // elements, for kArray
  int64_t invalid_raw = -1;  // raw value meaning "invalid" (decoded as null); -1 = none
  uint32_t bool_mask = 0;    // kBool: bit to test; 0 = compare with true_raw
  int64_t true_raw = 1;      // kBool with bool_mask 0: raw value meaning true (e.g. 0xF1)
  int64_t false_raw = 0;     // kBool with bool_mask 0: raw value meaning false (e.g. 0xF0)
  std::span<const EnumEntry> enum_names{};
  EnumStyle enum_style = EnumStyle::kRawThenName;
  Quirk quirk = Quirk::kNone;
  std::string_view unit{};  // human unit for docs ("km/h", "mV"...)
};

enum class MessageKind : uint8_t {
  kData,       // fields as listed
  kKeyword,    // fixed ASCII keyword: READY, LOCK, UNLOCK, SHUTDOWN, HANDSHAKE, CLEAR, ACK...
  kModelInfo,  // 64-byte MODEL/SN/HW/FW block, decoded as message "device_info"
  kFaultWord,  // 4-byte fault word
};

enum class SpecVersion : uint8_t { kV462, kV30 };

struct MessageDesc {
  std::string_view name;  // "mc_status", "bms_cells", "device_info", "ready"...
  uint16_t can_id;
  uint8_t function;
  uint8_t length;  // n, the number of DATA bytes
  Mode mode;
  MessageKind kind = MessageKind::kData;
  std::span<const FieldDesc> fields{};
  std::string_view keyword{};                   // kKeyword: the ASCII text
  FaultSource fault_source = FaultSource::kMc;  // kFaultWord
  SpecVersion version = SpecVersion::kV462;
  std::string_view title{};  // one-line description for docs and --list

  uint16_t command() const { return static_cast<uint16_t>((function << 8) | length); }
  Node source() const { return source_of(can_id); }
  Node target() const { return target_of(can_id); }
};

class Catalogue {
 public:
  // Every V4.6.2 message of §3.1 and the V3.0-only messages of §5.2 whose layout is legible.
  // Per-lock families (0x7n0 broadcasts, 0x767..0x76B commands) are expanded per node.
  static const Catalogue& standard();

  explicit Catalogue(std::vector<MessageDesc> messages);

  // A message is identified by (CAN ID, function code, n): the spec reuses one function code
  // for two messages exactly once (0x763: read 0x7000 and "SHUTDOWN" 0x7008).
  const MessageDesc* find(uint16_t can_id, uint8_t function, uint8_t length) const;
  // First message with this ID and function, whatever its length (nullptr when none). decode()
  // uses it to tell "unknown" from "known, but the length differs".
  const MessageDesc* find(uint16_t can_id, uint8_t function) const;
  // First message with this name on this ID (for encoding by name).
  const MessageDesc* find(std::string_view name, uint16_t can_id) const;
  std::span<const MessageDesc> messages() const { return messages_; }

 private:
  std::vector<MessageDesc> messages_;
  // (id << 16 | function << 8 | length) -> position, sorted.
  std::vector<std::pair<uint32_t, uint32_t>> index_;
};

}  // namespace motinova
