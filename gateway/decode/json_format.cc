#include "gateway/decode/json_format.h"

#include <fmt/format.h>

#include <cmath>

#include "motinova/faults.h"

namespace fleetgw::decode {
namespace {

using motinova::FieldKind;
using json = nlohmann::ordered_json;

double tidy(double v) {
  // Print 25.3, not 25.300000000000001: round to the nearest micro-unit.
  const double r = std::round(v * 1e6) / 1e6;
  return r == 0.0 ? 0.0 : r;
}

json number(const motinova::FieldValue& v) {
  const auto& f = *v.field;
  if (f.scale == 1.0 && f.bias == std::floor(f.bias) && v.value == std::floor(v.value)) {
    return static_cast<int64_t>(v.value);
  }
  return tidy(v.value);
}

std::string hex_bytes(std::span<const uint8_t> bytes) {
  std::string out;
  out.reserve(bytes.size() * 2);
  for (uint8_t b : bytes) out += fmt::format("{:02X}", b);
  return out;
}

json fault_word(const motinova::DecodedMessage& m, const motinova::FieldValue& v) {
  json active = json::array();
  const auto source = m.desc->fault_source;
  motinova::for_each_active_fault(
      source, static_cast<uint32_t>(v.raw), [&](uint32_t mask, const motinova::FaultDef* def) {
        const int bit = std::countr_zero(mask);
        if (def) {
          active.push_back({{"code", def->code >= 0 ? json(def->code) : json(nullptr)},
                            {"name", def->name},
                            {"severity", motinova::severity_name(def->severity)},
                            {"bit", bit}});
        } else {
          active.push_back({{"code", nullptr},
                            {"name", fmt::format("undefined_bit_{}", bit)},
                            {"severity", "warning"},
                            {"bit", bit}});
        }
      });
  return active;
}

}  // namespace

std::string hex_id(uint32_t value, int digits) {
  return fmt::format("0x{:0{}X}", value, digits);
}

std::string lock_kind(motinova::Node node, const motinova::DecodeOptions& options) {
  if (!motinova::is_lock(node)) return "";
  return options.lock_kinds[static_cast<std::size_t>(motinova::lock_index(node))];
}

json fields_to_json(const motinova::DecodedMessage& m, const motinova::DecodeOptions& options) {
  json fields = json::object();
  if (!m.desc) {
    fields["data"] = hex_bytes(m.frame->data.span());
    if (m.status == motinova::DecodeStatus::kLengthMismatch) fields["length_mismatch"] = true;
    return fields;
  }
  const motinova::Node src = m.desc->source();
  if (m.desc->kind == motinova::MessageKind::kModelInfo) fields["node"] = motinova::node_name(src);
  if (m.desc->name == "lock_status") fields["lock"] = lock_kind(src, options);
  if (m.desc->kind == motinova::MessageKind::kKeyword) fields["keyword"] = m.desc->keyword;

  for (const auto& v : m.values()) {
    const auto& f = *v.field;
    const std::string name(f.name);
    if (f.kind == FieldKind::kReserved) continue;
    if (!v.valid) {
      fields[name] = nullptr;
      continue;
    }
    switch (f.kind) {
      case FieldKind::kUnsigned:
      case FieldKind::kSigned:
        fields[name] = number(v);
        break;
      case FieldKind::kBool:
        fields[name] = v.value != 0.0;
        break;
      case FieldKind::kFlags:
        fields[name] = v.raw;
        break;
      case FieldKind::kEnum: {
        const json label = v.text.empty() ? json(fmt::format("0x{:02X}", v.raw)) : json(v.text);
        if (f.enum_style == motinova::EnumStyle::kRawThenName) {
          fields[name] = v.raw;
          fields[name + "_name"] = label;
        } else {
          fields[name] = label;
          fields[name + "_raw"] = v.raw;
        }
        break;
      }
      case FieldKind::kAscii:
        fields[name] = std::string(v.text);
        break;
      case FieldKind::kBytes:
        fields[name] = hex_bytes(v.bytes);
        break;
      case FieldKind::kArray: {
        json arr = json::array();
        for (std::size_t i = 0; i < f.count; ++i) {
          const auto e = m.element(f.name, i);
          if (!e) break;
          const double scaled = static_cast<double>(*e) * f.scale + f.bias;
          arr.push_back(f.scale == 1.0 ? json(static_cast<int64_t>(scaled)) : json(tidy(scaled)));
        }
        fields[name] = std::move(arr);
        break;
      }
      case FieldKind::kFaultWord:
        fields[name] = v.raw;
        fields["active"] = fault_word(m, v);
        break;
      case FieldKind::kReserved:
        break;
    }
  }
  return fields;
}

json message_to_json(const motinova::DecodedMessage& m, motinova::Micros ts,
                     const motinova::DecodeOptions& options) {
  const auto& frame = *m.frame;
  json j;
  j["ts"] = static_cast<double>(ts.count()) / 1e6;
  j["can_id"] = hex_id(frame.can_id);
  j["src"] = motinova::node_name(motinova::source_of(frame.can_id));
  j["dst"] = motinova::node_name(motinova::target_of(frame.can_id));
  j["mode"] = motinova::mode_name(frame.mode);
  j["function"] = hex_id(frame.function, 2);
  j["message"] = m.name();
  if (!m.mode_matches) j["mode_mismatch"] = true;
  j["fields"] = fields_to_json(m, options);
  return j;
}

json error_to_json(const motinova::ReassemblyErrorEvent& e) {
  return {{"ts", static_cast<double>(e.timestamp.count()) / 1e6},
          {"can_id", hex_id(e.can_id)},
          {"error", motinova::reassembly_error_name(e.kind)},
          {"bytes_dropped", e.bytes_dropped}};
}

}  // namespace fleetgw::decode
