// The signal catalogue (issue 29): every decoded field of every catalogue message under one
// stable, dotted name, with its unit, its type and the message it comes from -- what a
// collection campaign names and what the backend receives. Derived from the message catalogue
// (catalogue.h) and the fault table (faults.h) at construction, never kept by hand, so a field
// added to a catalogue_*.cc table is a signal at once.
//
// Naming (docs/campaigns.md):
//   <node>.<message>.<field>            mc.status.motor_temp_c, bms.status.soc_pct
//   <node>.<message>.<field>[i]         bms.cells.cells_mv[7] (element i, 0-based: cell 8)
//   <node>.<message>.<fault bit name>   bms.faults.charge_over_voltage_alarm (bool, per defined
//                                       bit of the fault table; `raw` is the whole word)
// <node> is motinova::node_name() of the message's source; <message> is the catalogue name with
// the node's family prefix removed ("mc_status" -> "status", "lock_status" -> "status" on
// lock1..lock5). When two catalogue messages of one node would get the same name (the V3.0
// layout of a message also in V4.6.2, one keyword on several IDs), the first in catalogue order
// keeps it and each later one gets "_<can id in hex>" appended ("mc.settings_714"). Reserved
// bytes and the fixed text of keyword messages are not signals; read requests have no fields.
//
// Contract: immutable after construction, safe to share between threads. Signal ids are indexes
// into signals(), stable for one build (names are what crosses the wire). read() never
// allocates for numeric signals and never throws.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "motinova/catalogue.h"
#include "motinova/codec.h"

namespace motinova {

enum class SignalType : uint8_t {
  kNumber,  // scaled value (raw * scale + bias, after option quirks), unit in `unit`
  kBool,    // 0 or 1
  kEnum,    // integer code; its name is in the decoded message (e.g. assist level)
  kFlags,   // a bit field as its integer
  kText,    // ASCII text (trimmed)
  kBytes,   // opaque bytes, as lower-case hex
};
// "number", "bool", "enum", "flags", "text", "bytes".
std::string_view signal_type_name(SignalType type);
// kNumber, kBool, kEnum, kFlags: a campaign may compare it with a threshold.
inline constexpr bool is_numeric(SignalType type) {
  return type != SignalType::kText && type != SignalType::kBytes;
}

struct Signal {
  uint32_t id = 0;   // index in SignalCatalogue::signals()
  std::string name;  // stable dotted name (see the naming rules above)
  const MessageDesc* message = nullptr;
  const FieldDesc* field = nullptr;
  int element = -1;         // kArray element, -1 otherwise
  uint32_t fault_mask = 0;  // a fault bit (one bit of the normalised word), 0 otherwise
  SignalType type = SignalType::kNumber;
  std::string_view unit{};  // "" when dimensionless
};

// A signal's value in one decoded message.
struct SignalValue {
  bool valid = false;                // false: the field carried its "invalid" sentinel (null)
  double number = 0.0;               // numeric types
  std::string_view text{};           // kText: view into the decoded frame
  std::span<const uint8_t> bytes{};  // kBytes
};

class SignalCatalogue {
 public:
  // The catalogue of Catalogue::standard() (built once, on first use).
  static const SignalCatalogue& standard();
  explicit SignalCatalogue(const Catalogue& catalogue);

  std::span<const Signal> signals() const { return signals_; }
  const Signal* find(std::string_view name) const;
  // The signals of one catalogue message, in field order (empty for unknown ones).
  std::span<const Signal> of_message(const MessageDesc* message) const;
  // The value of `signal` in `message` (which must be a decoding of signal.message);
  // nullopt when the message does not carry the field.
  static std::optional<SignalValue> read(const Signal& signal, const DecodedMessage& message);
  // The same from the FieldValue of signal.field (callers that walk values() once).
  static SignalValue read(const Signal& signal, const FieldValue& value, ByteOrder order);

 private:
  std::vector<Signal> signals_;
  std::unordered_map<std::string_view, uint32_t> by_name_;  // views into signals_
  std::unordered_map<const MessageDesc*, std::pair<uint32_t, uint32_t>> by_message_;
};

// Lower-case hex of `bytes` (kBytes values in text form).
std::string hex_text(std::span<const uint8_t> bytes);

}  // namespace motinova
