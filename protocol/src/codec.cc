// Catalogue-driven decoding and encoding of application-frame DATA.
//
// The decoder is on the hot path (every frame on the bus): it never allocates and never throws.
// The writer is used for commands and tests, so it validates everything and throws with the
// message and field named.

#include "motinova/codec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

namespace motinova {
namespace {

// U14: where the MC may answer the IOT's reads.
constexpr uint16_t kMcBroadcastId = 0x710;
constexpr uint16_t kMcToObcId = 0x713;
constexpr uint16_t kMcToIotId = 0x716;

// U17: the nine event counters of 0x725/0x5028 start at offset 12, two bytes each.
constexpr std::size_t kPackStatsFirstCounter = 12;

// U9 auto-detection: a plausible 13S..16S pack voltage in mV.
constexpr uint64_t kAutoVoltageMin = 20'000;
constexpr uint64_t kAutoVoltageMax = 60'000;

bool is_integer_kind(FieldKind k) {
  switch (k) {
    case FieldKind::kUnsigned:
    case FieldKind::kSigned:
    case FieldKind::kBool:
    case FieldKind::kEnum:
    case FieldKind::kFlags:
    case FieldKind::kFaultWord:
      return true;
    default:
      return false;
  }
}

const FieldDesc* field_with_quirk(const MessageDesc& desc, Quirk q) {
  for (const FieldDesc& f : desc.fields) {
    if (f.quirk == q) return &f;
  }
  return nullptr;
}

// The U9 pair of a message, when it has one.
struct VoltageCurrentPair {
  const FieldDesc* voltage = nullptr;
  const FieldDesc* current = nullptr;
  bool present() const { return voltage && current && voltage->size == current->size; }
};

VoltageCurrentPair voltage_current_pair(const MessageDesc& desc) {
  return {field_with_quirk(desc, Quirk::kMcVoltage), field_with_quirk(desc, Quirk::kMcCurrent)};
}

// Whether the voltage sits at the current's catalogue offset and vice versa.
bool voltage_current_swapped(const VoltageCurrentPair& pair, std::span<const uint8_t> data,
                             const DecodeOptions& options) {
  if (!pair.present()) return false;
  switch (options.mc_voltage_current_order) {
    case McVoltageCurrentOrder::kVoltageFirst:
      return false;
    case McVoltageCurrentOrder::kCurrentFirst:
      return true;
    case McVoltageCurrentOrder::kAuto: {
      auto plausible = [&](const FieldDesc& f) {
        const uint64_t mv = read_uint(data.subspan(f.offset, f.size), options.data_order);
        return mv >= kAutoVoltageMin && mv <= kAutoVoltageMax;
      };
      // Keep the documented order unless only the other position looks like a voltage.
      return !plausible(*pair.voltage) && plausible(*pair.current);
    }
  }
  return false;
}

// U17: where the pack-statistics fields sit under the configured reading.
std::size_t pack_stats_offset(const FieldDesc& f, const DecodeOptions& options) {
  switch (f.quirk) {
    case Quirk::kPackDischargeCurrent:
    case Quirk::kPackChargeCurrent:
      if (options.pack_stats_discharge_current_first) return f.offset;
      // The two currents trade places: offset 2 <-> offset 4.
      return f.quirk == Quirk::kPackDischargeCurrent ? f.offset + 2u : f.offset - 2u;
    case Quirk::kPackCounter:
      for (std::size_t i = 0; i < options.pack_stats_counter_order.size(); ++i) {
        if (options.pack_stats_counter_order[i] == f.name) return kPackStatsFirstCounter + 2 * i;
      }
      return f.offset;
    default:
      return f.offset;
  }
}

std::size_t placed_offset(const FieldDesc& f, const VoltageCurrentPair& pair, bool swapped,
                          const DecodeOptions& options) {
  if (swapped && pair.present()) {
    if (&f == pair.voltage) return pair.current->offset;
    if (&f == pair.current) return pair.voltage->offset;
  }
  return pack_stats_offset(f, options);
}

// U11/U17: factor from the wire unit to the unit in the field's name.
double unit_factor(const FieldDesc& f, const DecodeOptions& options) {
  constexpr double kPi = 3.14159265358979323846;
  switch (f.quirk) {
    case Quirk::kWheelSize:
      switch (options.wheel_size_unit) {
        case WheelSizeUnit::kCircumferenceCm:
          return 1.0;
        case WheelSizeUnit::kDiameterCm:
          return kPi;
        case WheelSizeUnit::kDiameterInch:
          return 2.54 * kPi;
      }
      return 1.0;
    case Quirk::kWheelAdjust:
      return options.wheel_adjust_unit == WheelAdjustUnit::kMm ? 0.1 : 1.0;
    case Quirk::kPackTime:
      return options.pack_stats_time_unit == PackTimeUnit::kMinutes ? 1.0 / 60.0 : 1.0;
    default:
      return 1.0;
  }
}

std::string_view trim_ascii(std::span<const uint8_t> bytes) {
  std::size_t n = bytes.size();
  while (n > 0 && (bytes[n - 1] == ' ' || bytes[n - 1] == '\0')) --n;
  return {reinterpret_cast<const char*>(bytes.data()), n};
}

std::string_view enum_name(const FieldDesc& f, int64_t raw, const DecodeOptions& options) {
  switch (f.quirk) {
    case Quirk::kAssist:
      for (const auto& entry : options.assist_names) {
        if (entry.value == raw && !entry.name.empty()) return entry.name;
      }
      return {};
    case Quirk::kLockState:
      if (raw >= 0 && static_cast<std::size_t>(raw) < options.lock_state_names.size()) {
        return options.lock_state_names[static_cast<std::size_t>(raw)];
      }
      return {};
    default:
      for (const EnumEntry& e : f.enum_names) {
        if (e.value == raw) return e.name;
      }
      return {};
  }
}

bool signed_reading(const FieldDesc& f, const DecodeOptions& options) {
  return f.kind == FieldKind::kSigned ||
         (f.quirk == Quirk::kMcCurrent && options.mc_current_signed);
}

// U4: the catalogue's convention is "charge positive"; flip when the bus says otherwise.
bool flip_sign(const FieldDesc& f, const DecodeOptions& options) {
  return f.quirk == Quirk::kBmsCurrent && !options.bms_current_charge_positive;
}

FieldValue decode_field(const FieldDesc& f, const MessageDesc& desc, std::span<const uint8_t> data,
                        std::size_t offset, const DecodeOptions& options) {
  FieldValue v;
  v.field = &f;
  const std::size_t count = f.kind == FieldKind::kArray ? f.count : 1;
  v.bytes = data.subspan(offset, f.size * count);

  switch (f.kind) {
    case FieldKind::kAscii:
      v.text = trim_ascii(v.bytes);
      if (desc.kind == MessageKind::kKeyword) {
        // Right ID and function but other bytes: keep the text, flag it as not the keyword.
        v.valid =
            std::equal(v.bytes.begin(), v.bytes.end(), desc.keyword.begin(), desc.keyword.end());
      }
      return v;
    case FieldKind::kBytes:
    case FieldKind::kArray:
    case FieldKind::kReserved:
      return v;
    case FieldKind::kFaultWord:
      v.raw = normalise_fault_word(v.bytes.first<4>(), options.data_order,
                                   fault_layout_for(desc.fault_source, options));
      v.value = static_cast<double>(v.raw);
      return v;
    default:
      break;
  }

  const uint64_t wire = read_uint(v.bytes, options.data_order);
  v.raw = signed_reading(f, options) ? sign_extend(wire, f.size) : static_cast<int64_t>(wire);
  if (f.invalid_raw >= 0 && wire == static_cast<uint64_t>(f.invalid_raw)) v.valid = false;

  switch (f.kind) {
    case FieldKind::kBool:
      if (f.bool_mask != 0) {
        v.value = (wire & f.bool_mask) != 0 ? 1.0 : 0.0;
      } else if (v.raw == f.true_raw) {
        v.value = 1.0;
      } else if (v.raw == f.false_raw) {
        v.value = 0.0;
      } else {
        v.valid = false;  // e.g. a headlight byte that is neither 0xF0 nor 0xF1
      }
      break;
    case FieldKind::kEnum:
      v.value = static_cast<double>(v.raw);
      v.text = enum_name(f, v.raw, options);
      break;
    case FieldKind::kFlags:
      v.value = static_cast<double>(v.raw);
      break;
    default:
      v.value = (static_cast<double>(v.raw) * f.scale + f.bias) * unit_factor(f, options);
      if (flip_sign(f, options)) v.value = -v.value;
      break;
  }
  return v;
}

std::size_t element_size(const FieldDesc& f) {
  return f.kind == FieldKind::kArray ? f.size : 1;
}

// U14: whether answers of the MC received on `can_id` are read as the 0x713 ones.
bool answers_as_mc_to_obc(uint16_t can_id, const DecodeOptions& options) {
  switch (options.mc_answer_id) {
    case McAnswerId::k713:
      return false;  // 0x713 itself is in the catalogue
    case McAnswerId::k716:
      return can_id == kMcToIotId;
    case McAnswerId::k710:
      return can_id == kMcBroadcastId;
    case McAnswerId::kAuto:
      return can_id == kMcToIotId || can_id == kMcBroadcastId;
  }
  return false;
}

// The MC's answers are its 0x713 report-mode messages (ACK, settings, parameter blocks).
const MessageDesc* mc_answer(const Catalogue& catalogue, uint8_t function, uint8_t length) {
  const MessageDesc* d = catalogue.find(kMcToObcId, function, length);
  return d != nullptr && d->mode == Mode::kReport ? d : nullptr;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// DecodedMessage

const FieldValue* DecodedMessage::find(std::string_view field) const {
  for (std::size_t i = 0; i < count_; ++i) {
    if (values_[i].field->name == field) return &values_[i];
  }
  return nullptr;
}

std::optional<double> DecodedMessage::number(std::string_view field) const {
  const FieldValue* v = find(field);
  if (!v || !v->valid || !is_integer_kind(v->field->kind)) return std::nullopt;
  return v->value;
}

std::optional<int64_t> DecodedMessage::raw(std::string_view field) const {
  const FieldValue* v = find(field);
  if (!v || !is_integer_kind(v->field->kind)) return std::nullopt;
  return v->raw;
}

std::string_view DecodedMessage::text(std::string_view field) const {
  const FieldValue* v = find(field);
  return v ? v->text : std::string_view{};
}

std::optional<uint64_t> DecodedMessage::element(std::string_view field, std::size_t i) const {
  const FieldValue* v = find(field);
  if (!v || (v->field->kind != FieldKind::kArray && v->field->kind != FieldKind::kBytes)) {
    return std::nullopt;
  }
  const std::size_t size = element_size(*v->field);
  if ((i + 1) * size > v->bytes.size()) return std::nullopt;
  return read_uint(v->bytes.subspan(i * size, size), data_order);
}

// ---------------------------------------------------------------------------------------------
// decode

void decode(const AppFrame& frame, const Catalogue& catalogue, const DecodeOptions& options,
            DecodedMessage& out) {
  out.clear();
  out.frame = &frame;
  out.desc = nullptr;
  out.mode_matches = true;
  out.data_order = options.data_order;

  const std::span<const uint8_t> data = frame.data.span();
  const MessageDesc* desc = data.size() <= 0xFF ? catalogue.find(frame.can_id, frame.function,
                                                                 static_cast<uint8_t>(data.size()))
                                                : nullptr;
  if (desc == nullptr && data.size() <= 0xFF && answers_as_mc_to_obc(frame.can_id, options)) {
    desc = mc_answer(catalogue, frame.function, static_cast<uint8_t>(data.size()));
  }
  if (desc == nullptr) {
    out.status = catalogue.find(frame.can_id, frame.function) != nullptr
                     ? DecodeStatus::kLengthMismatch
                     : DecodeStatus::kUnknownMessage;
    return;
  }
  out.desc = desc;
  out.status = DecodeStatus::kOk;
  out.mode_matches = frame.mode == desc->mode;

  const VoltageCurrentPair pair = voltage_current_pair(*desc);
  const bool swapped = voltage_current_swapped(pair, data, options);
  for (const FieldDesc& f : desc->fields) {
    if (f.kind == FieldKind::kReserved) continue;
    out.add(decode_field(f, *desc, data, placed_offset(f, pair, swapped, options), options));
  }
}

// ---------------------------------------------------------------------------------------------
// Fault words (U3)

uint32_t normalise_fault_word(std::span<const uint8_t, 4> wire, ByteOrder order,
                              FaultWordLayout layout) {
  switch (layout) {
    case FaultWordLayout::kDocumented:
      return static_cast<uint32_t>(read_uint(wire, order));
    case FaultWordLayout::kSwappedGroups: {
      const auto v = static_cast<uint32_t>(read_uint(wire, order));
      return (v << 16) | (v >> 16);
    }
    case FaultWordLayout::kTwoWordsLowFirst: {
      const auto low = static_cast<uint32_t>(read_uint(wire.first<2>(), order));
      const auto high = static_cast<uint32_t>(read_uint(wire.last<2>(), order));
      return (high << 16) | low;
    }
  }
  return 0;
}

void write_fault_word(uint32_t normalised, ByteOrder order, FaultWordLayout layout,
                      std::span<uint8_t, 4> wire) {
  switch (layout) {
    case FaultWordLayout::kDocumented:
      write_uint(wire, normalised, order);
      return;
    case FaultWordLayout::kSwappedGroups:
      write_uint(wire, (normalised << 16) | (normalised >> 16), order);
      return;
    case FaultWordLayout::kTwoWordsLowFirst:
      write_uint(wire.first<2>(), normalised & 0xFFFFu, order);
      write_uint(wire.last<2>(), normalised >> 16, order);
      return;
  }
}

FaultWordLayout fault_layout_for(FaultSource source, const DecodeOptions& options) {
  switch (source) {
    case FaultSource::kMc:
      return options.mc_fault_layout;
    case FaultSource::kBms:
      return options.bms_fault_layout;
    default:
      return options.other_fault_layout;
  }
}

// ---------------------------------------------------------------------------------------------
// MessageWriter

MessageWriter::MessageWriter(const MessageDesc& desc, const DecodeOptions& options)
    : desc_(desc), options_(options) {
  data_.resize(desc_.length);
  // Unset text is space-padded as the spec requires (§3.0); everything else stays 0x00.
  for (const FieldDesc& f : desc_.fields) {
    if (f.kind == FieldKind::kAscii) std::fill_n(data_.data() + f.offset, f.size, ' ');
  }
  if (desc_.kind == MessageKind::kKeyword) {
    const std::size_t n = std::min<std::size_t>(desc_.keyword.size(), desc_.length);
    std::copy_n(desc_.keyword.begin(), n, data_.data());
  }
}

std::string MessageWriter::where() const {
  char buf[48];
  std::snprintf(buf, sizeof buf, " (0x%03X/0x%04X)", static_cast<unsigned>(desc_.can_id),
                static_cast<unsigned>(desc_.command()));
  return "MessageWriter: message " + std::string(desc_.name) + buf;
}

const FieldDesc& MessageWriter::field(std::string_view name) const {
  for (const FieldDesc& f : desc_.fields) {
    if (f.kind != FieldKind::kReserved && f.name == name) return f;
  }
  throw std::invalid_argument(where() + ": no field '" + std::string(name) + "'");
}

std::size_t MessageWriter::offset_of(const FieldDesc& f) const {
  // kAuto can only be resolved on receive; a sender uses the documented order.
  const bool swapped = options_.mc_voltage_current_order == McVoltageCurrentOrder::kCurrentFirst;
  return placed_offset(f, voltage_current_pair(desc_), swapped, options_);
}

void MessageWriter::put(const FieldDesc& f, int64_t raw, std::string_view what) {
  auto fail = [&](const std::string& why) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                "': " + std::string(what) + " " + why);
  };
  const std::size_t offset = offset_of(f);
  if (f.kind == FieldKind::kFaultWord) {
    if (raw < 0 || raw > int64_t{0xFFFFFFFF}) fail("does not fit a 32-bit fault word");
    write_fault_word(static_cast<uint32_t>(raw), options_.data_order,
                     fault_layout_for(desc_.fault_source, options_),
                     std::span<uint8_t, 4>(data_.data() + offset, 4));
    return;
  }
  const unsigned bits = 8u * f.size;
  int64_t lo = 0;
  int64_t hi = static_cast<int64_t>((uint64_t{1} << bits) - 1);
  if (signed_reading(f, options_)) {
    lo = -(int64_t{1} << (bits - 1));
    hi = (int64_t{1} << (bits - 1)) - 1;
  }
  if (raw < lo || raw > hi) {
    fail("is out of range " + std::to_string(lo) + ".." + std::to_string(hi) + " for a " +
         std::to_string(f.size) + "-byte field");
  }
  write_uint(std::span<uint8_t>(data_.data() + offset, f.size), static_cast<uint64_t>(raw),
             options_.data_order);
}

MessageWriter& MessageWriter::raw(std::string_view name, int64_t raw) {
  const FieldDesc& f = field(name);
  if (!is_integer_kind(f.kind)) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                "' is not an integer field (use text() or element())");
  }
  put(f, raw, "raw value " + std::to_string(raw));
  return *this;
}

MessageWriter& MessageWriter::value(std::string_view name, double physical) {
  const FieldDesc& f = field(name);
  if (f.kind == FieldKind::kBool) return boolean(name, physical != 0.0);
  if (!is_integer_kind(f.kind) || f.kind == FieldKind::kFaultWord) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                "' has no physical value (use raw(), text() or element())");
  }
  const std::string what = "value " + std::to_string(physical);
  if (!std::isfinite(physical)) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "': " + what +
                                " is not finite");
  }
  const double signed_physical = flip_sign(f, options_) ? -physical : physical;
  const double scaled = std::round((signed_physical / unit_factor(f, options_) - f.bias) / f.scale);
  // Beyond ±2^62 no field can hold it; checking here keeps the cast below defined.
  constexpr double kLimit = 4.6e18;
  if (scaled < -kLimit || scaled > kLimit) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "': " + what +
                                " is out of range");
  }
  put(f, static_cast<int64_t>(scaled), what);
  return *this;
}

MessageWriter& MessageWriter::boolean(std::string_view name, bool on) {
  const FieldDesc& f = field(name);
  if (f.kind != FieldKind::kBool) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "' is not a boolean");
  }
  if (f.bool_mask == 0) {
    put(f, on ? f.true_raw : f.false_raw, on ? "true" : "false");
    return *this;
  }
  // A masked flag shares its byte(s) with other flags: change only its own bit.
  const std::span<uint8_t> bytes(data_.data() + offset_of(f), f.size);
  uint64_t current = read_uint(bytes, options_.data_order);
  current = on ? (current | f.bool_mask) : (current & ~uint64_t{f.bool_mask});
  write_uint(bytes, current, options_.data_order);
  return *this;
}

MessageWriter& MessageWriter::text(std::string_view name, std::string_view ascii) {
  const FieldDesc& f = field(name);
  if (f.kind == FieldKind::kEnum) {
    for (int64_t raw = 0; raw < (int64_t{1} << (8 * f.size)) && raw < 256; ++raw) {
      const std::string_view n = enum_name(f, raw, options_);
      if (!n.empty() && n == ascii) {
        put(f, raw, "name '" + std::string(ascii) + "'");
        return *this;
      }
    }
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                "': no value is named '" + std::string(ascii) + "'");
  }
  if (f.kind != FieldKind::kAscii) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                "' is not a text field");
  }
  if (ascii.size() > f.size) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "': text of " +
                                std::to_string(ascii.size()) + " characters is longer than " +
                                std::to_string(f.size));
  }
  for (std::size_t i = 0; i < ascii.size(); ++i) {
    const auto c = static_cast<unsigned char>(ascii[i]);
    if (c < 0x20 || c > 0x7E) {
      throw std::invalid_argument(where() + ": field '" + std::string(f.name) +
                                  "': non-printable character at position " + std::to_string(i));
    }
  }
  uint8_t* out = data_.data() + f.offset;
  std::copy(ascii.begin(), ascii.end(), out);
  std::fill(out + ascii.size(), out + f.size, ' ');
  return *this;
}

MessageWriter& MessageWriter::element(std::string_view name, std::size_t index, uint64_t raw) {
  const FieldDesc& f = field(name);
  if (f.kind != FieldKind::kArray && f.kind != FieldKind::kBytes) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "' is not an array");
  }
  const std::size_t size = element_size(f);
  const std::size_t count = f.kind == FieldKind::kArray ? f.count : f.size;
  if (index >= count) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "': index " +
                                std::to_string(index) + " beyond " + std::to_string(count) +
                                " elements");
  }
  if (size < 8 && raw >= (uint64_t{1} << (8 * size))) {
    throw std::invalid_argument(where() + ": field '" + std::string(f.name) + "': element " +
                                std::to_string(raw) + " does not fit " + std::to_string(size) +
                                " byte(s)");
  }
  write_uint(std::span<uint8_t>(data_.data() + f.offset + index * size, size), raw,
             options_.data_order);
  return *this;
}

AppFrame MessageWriter::frame() const {
  return frame(desc_.can_id);
}

AppFrame MessageWriter::frame(uint16_t can_id) const {
  AppFrame f;
  f.can_id = can_id;
  f.mode = desc_.mode;
  f.function = desc_.function;
  f.data = data_;
  return f;
}

}  // namespace motinova
