// The signal catalogue, derived from the message catalogue and the fault table (see the header
// for the naming rules).

#include "motinova/signal_catalogue.h"

#include <cstdio>
#include <set>
#include <stdexcept>

namespace motinova {
namespace {

// The prefix a node's message names carry in the catalogue ("mc_status" on the MC).
std::string_view family_prefix(Node node) {
  switch (node) {
    case Node::kMc:
      return "mc_";
    case Node::kBms:
      return "bms_";
    case Node::kObc:
      return "obc_";
    case Node::kHmi:
      return "hmi_";
    case Node::kIot:
      return "iot_";
    case Node::kCdl:
      return "cdl_";
    default:
      return is_lock(node) ? "lock_" : "";
  }
}

SignalType type_of(const FieldDesc& f) {
  switch (f.kind) {
    case FieldKind::kBool:
      return SignalType::kBool;
    case FieldKind::kEnum:
      return SignalType::kEnum;
    case FieldKind::kFlags:
    case FieldKind::kFaultWord:
      return SignalType::kFlags;
    case FieldKind::kAscii:
      return SignalType::kText;
    case FieldKind::kBytes:
      return SignalType::kBytes;
    default:
      return SignalType::kNumber;
  }
}

double element_value(const FieldDesc& f, std::span<const uint8_t> bytes, int element,
                     ByteOrder order) {
  const std::size_t at = static_cast<std::size_t>(element) * f.size;
  uint64_t raw = 0;
  for (std::size_t i = 0; i < f.size; ++i) {
    const std::size_t b = order == ByteOrder::kBig ? at + i : at + f.size - 1 - i;
    raw = (raw << 8) | bytes[b];
  }
  return static_cast<double>(raw) * f.scale + f.bias;
}

}  // namespace

std::string_view signal_type_name(SignalType type) {
  switch (type) {
    case SignalType::kNumber:
      return "number";
    case SignalType::kBool:
      return "bool";
    case SignalType::kEnum:
      return "enum";
    case SignalType::kFlags:
      return "flags";
    case SignalType::kText:
      return "text";
    case SignalType::kBytes:
      return "bytes";
  }
  return "number";
}

const SignalCatalogue& SignalCatalogue::standard() {
  static const SignalCatalogue catalogue(Catalogue::standard());
  return catalogue;
}

SignalCatalogue::SignalCatalogue(const Catalogue& catalogue) {
  std::set<std::string, std::less<>> message_names;  // "<node>.<message>" already given
  for (const MessageDesc& m : catalogue.messages()) {
    if (m.kind == MessageKind::kKeyword || m.fields.empty()) continue;
    const std::string node(node_name(m.source()));
    std::string_view short_name = m.name;
    if (const auto p = family_prefix(m.source()); !p.empty() && short_name.starts_with(p)) {
      short_name.remove_prefix(p.size());
    }
    std::string prefix = node + "." + std::string(short_name);
    if (message_names.contains(prefix)) {
      char id[8];
      std::snprintf(id, sizeof id, "_%03x", static_cast<unsigned>(m.can_id));
      prefix += id;
      if (message_names.contains(prefix)) {
        throw std::logic_error("signal catalogue: two messages named " + prefix);
      }
    }
    message_names.insert(prefix);

    const auto first = static_cast<uint32_t>(signals_.size());
    auto add = [&](std::string name, const FieldDesc& f, int element, uint32_t mask,
                   SignalType type) {
      Signal s;
      s.id = static_cast<uint32_t>(signals_.size());
      s.name = std::move(name);
      s.message = &m;
      s.field = &f;
      s.element = element;
      s.fault_mask = mask;
      s.type = type;
      s.unit = f.unit;
      signals_.push_back(std::move(s));
    };
    for (const FieldDesc& f : m.fields) {
      if (f.kind == FieldKind::kReserved) continue;
      const std::string base = prefix + "." + std::string(f.name);
      if (f.kind == FieldKind::kArray) {
        for (int i = 0; i < f.count; ++i) {
          add(base + "[" + std::to_string(i) + "]", f, i, 0, SignalType::kNumber);
        }
        continue;
      }
      add(base, f, -1, 0, type_of(f));
      if (f.kind == FieldKind::kFaultWord) {
        for (const FaultDef& def : fault_table(m.fault_source)) {
          add(prefix + "." + std::string(def.name), f, -1, def.mask, SignalType::kBool);
        }
      }
    }
    by_message_[&m] = {first, static_cast<uint32_t>(signals_.size())};
  }
  by_name_.reserve(signals_.size());
  for (const Signal& s : signals_) {
    if (!by_name_.emplace(s.name, s.id).second) {
      throw std::logic_error("signal catalogue: duplicate signal " + s.name);
    }
  }
}

const Signal* SignalCatalogue::find(std::string_view name) const {
  const auto it = by_name_.find(name);
  return it == by_name_.end() ? nullptr : &signals_[it->second];
}

std::span<const Signal> SignalCatalogue::of_message(const MessageDesc* message) const {
  const auto it = by_message_.find(message);
  if (it == by_message_.end()) return {};
  return std::span<const Signal>(signals_).subspan(it->second.first,
                                                   it->second.second - it->second.first);
}

SignalValue SignalCatalogue::read(const Signal& signal, const FieldValue& value, ByteOrder order) {
  SignalValue out;
  out.valid = value.valid;
  if (signal.element >= 0) {
    out.valid = true;
    out.number = element_value(*signal.field, value.bytes, signal.element, order);
    return out;
  }
  if (signal.fault_mask != 0) {
    out.valid = true;
    out.number = (static_cast<uint64_t>(value.raw) & signal.fault_mask) != 0 ? 1.0 : 0.0;
    return out;
  }
  switch (signal.type) {
    case SignalType::kText:
      out.text = value.text;
      out.valid = true;
      break;
    case SignalType::kBytes:
      out.bytes = value.bytes;
      out.valid = true;
      break;
    default:
      out.number = value.value;
      break;
  }
  return out;
}

std::optional<SignalValue> SignalCatalogue::read(const Signal& signal,
                                                 const DecodedMessage& message) {
  for (const FieldValue& v : message.values()) {
    if (v.field == signal.field) return read(signal, v, message.data_order);
  }
  return std::nullopt;
}

std::string hex_text(std::span<const uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (const uint8_t b : bytes) {
    out.push_back(kDigits[b >> 4]);
    out.push_back(kDigits[b & 0xF]);
  }
  return out;
}

}  // namespace motinova
