// Decoding application frames into typed field values, and encoding values back into frames.
//
// Contract: decode() never allocates and never throws; an (ID, function) pair not in the
// catalogue, or one whose length differs from the catalogue, decodes as message "unknown"
// (raw data kept), never as an error. A DecodedMessage holds views into the AppFrame it came
// from and must not outlive it; names taken from option tables (assist U7, lock state U19) are
// views into the DecodeOptions, which must outlive it too (do not pass a temporary). MessageWriter
// validates every value and throws std::invalid_argument with the field name when a value does not
// fit.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "motinova/catalogue.h"
#include "motinova/frame.h"
#include "motinova/options.h"

namespace motinova {

inline constexpr std::size_t kMaxFields = 48;

struct FieldValue {
  const FieldDesc* field = nullptr;
  bool valid = true;        // false when raw == invalid_raw (JSON null)
  int64_t raw = 0;          // integer on the wire (after sign extension / fault normalisation)
  double value = 0.0;       // raw * scale + bias, after option quirks (e.g. sign flip)
  std::string_view text{};  // kAscii (trimmed), kEnum name (empty when unnamed)
  std::span<const uint8_t> bytes{};  // kArray, kBytes: the field's bytes in the frame
};

enum class DecodeStatus : uint8_t {
  kOk,
  kUnknownMessage,  // (ID, function) not in the catalogue
  kLengthMismatch,  // in the catalogue, but n differs: decoded as unknown
};

class DecodedMessage {
 public:
  const AppFrame* frame = nullptr;
  const MessageDesc* desc = nullptr;  // nullptr for unknown messages
  DecodeStatus status = DecodeStatus::kUnknownMessage;
  bool mode_matches = true;  // MODE equals the catalogue's
  ByteOrder data_order = ByteOrder::kBig;

  std::string_view name() const { return desc ? desc->name : std::string_view{"unknown"}; }
  std::span<const FieldValue> values() const { return {values_.data(), count_}; }
  const FieldValue* find(std::string_view field) const;
  // Scaled value of a valid numeric/bool/enum field; nullopt when absent or invalid.
  std::optional<double> number(std::string_view field) const;
  // Wire integer of an integer-like field (also when it equals the "invalid" sentinel).
  std::optional<int64_t> raw(std::string_view field) const;
  std::string_view text(std::string_view field) const;
  // Element i of a kArray field, decoded in data_order.
  std::optional<uint64_t> element(std::string_view field, std::size_t i) const;

  void add(const FieldValue& v) {
    if (count_ < kMaxFields) values_[count_++] = v;
  }
  void clear() { count_ = 0; }

 private:
  std::array<FieldValue, kMaxFields> values_{};
  std::size_t count_ = 0;
};

// Decodes `frame` into `out` (reused to avoid allocation). `out` may point into `catalogue` and
// `options` (enum and assist names), so both must outlive it: temporaries are refused.
void decode(const AppFrame& frame, const Catalogue& catalogue, const DecodeOptions& options,
            DecodedMessage& out);
void decode(const AppFrame&, const Catalogue&, DecodeOptions&&, DecodedMessage&) = delete;

// Fault word normalisation (U3): wire bytes -> normalised word (documented high group in the
// high 16 bits), and back.
uint32_t normalise_fault_word(std::span<const uint8_t, 4> wire, ByteOrder order,
                              FaultWordLayout layout);
void write_fault_word(uint32_t normalised, ByteOrder order, FaultWordLayout layout,
                      std::span<uint8_t, 4> wire);
FaultWordLayout fault_layout_for(FaultSource source, const DecodeOptions& options);

// Builds the DATA of one catalogue message. Unset fields and reserved bytes are 0x00; keyword
// messages are pre-filled with their keyword and model-info blocks with spaces.
class MessageWriter {
 public:
  MessageWriter(const MessageDesc& desc, const DecodeOptions& options);

  MessageWriter& raw(std::string_view field, int64_t raw);        // wire value
  MessageWriter& value(std::string_view field, double physical);  // scaled value
  MessageWriter& boolean(std::string_view field, bool on);
  MessageWriter& text(std::string_view field, std::string_view ascii);  // space-padded
  MessageWriter& element(std::string_view field, std::size_t index, uint64_t raw);

  AppFrame frame() const;
  AppFrame frame(uint16_t can_id) const;  // same message on another ID (e.g. another lock)

 private:
  const FieldDesc& field(std::string_view name) const;
  std::string where() const;  // "message mc_status (0x710/0x1020)" for error texts
  std::size_t offset_of(const FieldDesc& f) const;  // applies the U9 position swap
  void put(const FieldDesc& f, int64_t raw, std::string_view what);
  const MessageDesc& desc_;
  DecodeOptions options_;  // a copy: a writer must not dangle when built from a temporary
  FixedBytes<kMaxData> data_;
};

}  // namespace motinova
