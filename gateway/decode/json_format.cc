#include "gateway/decode/json_format.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>

#include "motinova/fault_names.h"

namespace fleetgw::decode {
namespace {

using motinova::FieldKind;

constexpr char kHex[] = "0123456789ABCDEF";

double tidy(double v) {
  // Print 25.3, not 25.300000000000001: round to the nearest micro-unit.
  const double r = std::round(v * 1e6) / 1e6;
  return r == 0.0 ? 0.0 : r;
}

void append_int(JsonBuffer& out, int64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, static_cast<std::size_t>(r.ptr - buf));
}

void append_key(JsonBuffer& out, bool& first, std::string_view key) {
  if (!first) out += ',';
  first = false;
  append_json_string(out, key);
  out += ':';
}

// A key made of a catalogue name and a suffix ("assist" + "_name").
void append_key(JsonBuffer& out, bool& first, std::string_view key, std::string_view suffix) {
  if (!first) out += ',';
  first = false;
  out += '"';
  out += key;  // catalogue names are plain identifiers
  out += suffix;
  out += "\":";
}

void append_number(JsonBuffer& out, const motinova::FieldValue& v) {
  const auto& f = *v.field;
  if (f.scale == 1.0 && f.bias == std::floor(f.bias) && v.value == std::floor(v.value)) {
    append_int(out, static_cast<int64_t>(v.value));
  } else {
    append_json_double(out, tidy(v.value));
  }
}

void append_hex_bytes(JsonBuffer& out, std::span<const uint8_t> bytes) {
  out += '"';
  for (uint8_t b : bytes) {
    out += kHex[b >> 4];
    out += kHex[b & 0xF];
  }
  out += '"';
}

// "0x710" with at least `digits` upper-case hex digits, quoted (as hex_id()).
void append_hex_id(JsonBuffer& out, uint32_t value, int digits) {
  char buf[12];
  int n = 0;
  do {
    buf[n++] = kHex[value & 0xF];
    value >>= 4;
  } while (value != 0 || n < digits);
  out += "\"0x";
  while (n > 0) out += buf[--n];
  out += '"';
}

void append_hex_byte_label(JsonBuffer& out, int64_t raw) {
  char buf[32];
  const auto r = fmt::format_to_n(buf, sizeof buf, "\"0x{:02X}\"", raw);
  out.append(buf, std::min(r.size, sizeof buf));
}

void append_faults(JsonBuffer& out, const motinova::DecodedMessage& m,
                   const motinova::FieldValue& v, const motinova::DecodeOptions& options) {
  out += '[';
  bool first_item = true;
  motinova::for_each_active_fault(
      m.desc->fault_source, static_cast<uint32_t>(v.raw), options,
      [&](uint32_t mask, const motinova::FaultDef* def) {
        if (!first_item) out += ',';
        first_item = false;
        const int bit = std::countr_zero(mask);
        out += "{\"code\":";
        if (def && def->code >= 0) {
          append_int(out, def->code);
        } else {
          out += "null";
        }
        out += ",\"name\":";
        if (def) {
          append_json_string(out, def->name);
        } else {
          out += "\"undefined_bit_";
          append_int(out, bit);
          out += '"';
        }
        out += ",\"severity\":";
        append_json_string(out, def ? motinova::severity_name(def->severity) : "warning");
        out += ",\"bit\":";
        append_int(out, bit);
        out += '}';
      });
  out += ']';
}

void append_field(JsonBuffer& out, bool& first, const motinova::DecodedMessage& m,
                  const motinova::FieldValue& v, const motinova::DecodeOptions& options) {
  const auto& f = *v.field;
  if (!v.valid) {
    append_key(out, first, f.name, "");
    out += "null";
    return;
  }
  switch (f.kind) {
    case FieldKind::kUnsigned:
    case FieldKind::kSigned:
      append_key(out, first, f.name, "");
      append_number(out, v);
      return;
    case FieldKind::kBool:
      append_key(out, first, f.name, "");
      out += v.value != 0.0 ? "true" : "false";
      return;
    case FieldKind::kFlags:
      append_key(out, first, f.name, "");
      append_int(out, v.raw);
      return;
    case FieldKind::kEnum: {
      auto label = [&] {
        if (v.text.empty()) {
          append_hex_byte_label(out, v.raw);
        } else {
          append_json_string(out, v.text);
        }
      };
      if (f.enum_style == motinova::EnumStyle::kRawThenName) {
        append_key(out, first, f.name, "");
        append_int(out, v.raw);
        append_key(out, first, f.name, "_name");
        label();
      } else {
        append_key(out, first, f.name, "");
        label();
        append_key(out, first, f.name, "_raw");
        append_int(out, v.raw);
      }
      return;
    }
    case FieldKind::kAscii:
      append_key(out, first, f.name, "");
      append_json_string(out, v.text);
      return;
    case FieldKind::kBytes:
      append_key(out, first, f.name, "");
      append_hex_bytes(out, v.bytes);
      return;
    case FieldKind::kArray: {
      append_key(out, first, f.name, "");
      out += '[';
      for (std::size_t i = 0; i < f.count && (i + 1) * f.size <= v.bytes.size(); ++i) {
        const uint64_t e = motinova::read_uint(v.bytes.subspan(i * f.size, f.size), m.data_order);
        if (i > 0) out += ',';
        const double scaled = static_cast<double>(e) * f.scale + f.bias;
        if (f.scale == 1.0) {
          append_int(out, static_cast<int64_t>(scaled));
        } else {
          append_json_double(out, tidy(scaled));
        }
      }
      out += ']';
      return;
    }
    case FieldKind::kFaultWord:
      append_key(out, first, f.name, "");
      append_int(out, v.raw);
      append_key(out, first, "active", "");
      append_faults(out, m, v, options);
      return;
    case FieldKind::kReserved:
      return;
  }
}

void append_ts(JsonBuffer& out, motinova::Micros ts) {
  append_json_double(out, static_cast<double>(ts.count()) / 1e6);
}

}  // namespace

void append_json_string(JsonBuffer& out, std::string_view text) {
  out += '"';
  // Plain runs (the whole string, nearly always) are appended in one go.
  auto plain = [](unsigned char c) { return c >= 0x20 && c < 0x80 && c != '"' && c != '\\'; };
  std::size_t i = 0;
  while (i < text.size()) {
    std::size_t run = i;
    while (run < text.size() && plain(static_cast<unsigned char>(text[run]))) ++run;
    out.append(text.data() + i, run - i);
    if (run == text.size()) break;
    i = run + 1;
    const char ch = text[run];
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20 || c >= 0x80) {
          // Control characters must be escaped; bytes beyond ASCII (bus text is ASCII, so these
          // are garbage) become the code points U+0080..U+00FF: always valid UTF-8 output.
          out += "\\u00";
          out += static_cast<char>(std::tolower(kHex[c >> 4]));
          out += static_cast<char>(std::tolower(kHex[c & 0xF]));
        } else {
          out += ch;
        }
    }
  }
  out += '"';
}

void append_json_double(JsonBuffer& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";  // as nlohmann::json
    return;
  }
  if (value == 0.0) {
    out += std::signbit(value) ? "-0.0" : "0.0";
    return;
  }
  // Shortest round-trip digits, then laid out as nlohmann::json (Grisu2 + format_buffer) does:
  // fixed notation for decimal exponents -4 < n <= 15, scientific otherwise.
  char sci[32];
  const auto r = std::to_chars(sci, sci + sizeof sci, value, std::chars_format::scientific);
  std::string_view s(sci, static_cast<std::size_t>(r.ptr - sci));
  if (s.front() == '-') {
    out += '-';
    s.remove_prefix(1);
  }
  const auto e_at = s.find('e');
  char digits[24];
  int k = 0;
  for (char c : s.substr(0, e_at)) {
    if (c != '.') digits[k++] = c;
  }
  int exp10 = 0;
  const auto exp_text = s.substr(e_at + 1);
  std::from_chars(exp_text.data() + (exp_text.front() == '+' ? 1 : 0),
                  exp_text.data() + exp_text.size(), exp10);
  const int n = exp10 + 1;  // position of the decimal point relative to the digits
  if (k <= n && n <= 15) {
    out.append(digits, static_cast<std::size_t>(k));
    out.append(static_cast<std::size_t>(n - k), '0');
    out += ".0";
  } else if (0 < n && n <= 15) {
    out.append(digits, static_cast<std::size_t>(n));
    out += '.';
    out.append(digits + n, static_cast<std::size_t>(k - n));
  } else if (-4 < n && n <= 0) {
    out += "0.";
    out.append(static_cast<std::size_t>(-n), '0');
    out.append(digits, static_cast<std::size_t>(k));
  } else {
    out += digits[0];
    if (k > 1) {
      out += '.';
      out.append(digits + 1, static_cast<std::size_t>(k - 1));
    }
    const int e = n - 1;
    out += e < 0 ? "e-" : "e+";
    const int a = e < 0 ? -e : e;
    if (a < 10) out += '0';
    append_int(out, a);
  }
}

void JsonBuffer::grow(std::size_t n) {
  const std::size_t used = size();
  const std::size_t capacity = std::max<std::size_t>({used + n, 2 * used, 4096});
  auto bigger = std::make_unique_for_overwrite<char[]>(capacity);
  if (used > 0) std::memcpy(bigger.get(), data_.get(), used);
  data_ = std::move(bigger);
  end_ = data_.get() + used;
  cap_ = data_.get() + capacity;
}

std::string hex_id(uint32_t value, int digits) {
  return fmt::format("0x{:0{}X}", value, digits);
}

std::string lock_kind(motinova::Node node, const motinova::DecodeOptions& options) {
  if (!motinova::is_lock(node)) return "";
  return options.lock_kinds[static_cast<std::size_t>(motinova::lock_index(node))];
}

void append_fields_json(JsonBuffer& out, const motinova::DecodedMessage& m,
                        const motinova::DecodeOptions& options) {
  out += '{';
  bool first = true;
  if (!m.desc) {
    append_key(out, first, "data");
    append_hex_bytes(out, m.frame->data.span());
    if (m.status == motinova::DecodeStatus::kLengthMismatch) {
      append_key(out, first, "length_mismatch");
      out += "true";
    }
    out += '}';
    return;
  }
  const motinova::Node src = m.desc->source();
  if (m.desc->kind == motinova::MessageKind::kModelInfo) {
    append_key(out, first, "node");
    append_json_string(out, motinova::node_name(src));
  }
  if (m.desc->name == "lock_status") {
    append_key(out, first, "lock");
    const std::size_t index = static_cast<std::size_t>(motinova::lock_index(src));
    append_json_string(out, motinova::is_lock(src) ? std::string_view(options.lock_kinds[index])
                                                   : std::string_view{});
  }
  // Keyword messages carry their text as the field "keyword" (valid or null), which takes the
  // place of the catalogue keyword.
  if (m.desc->kind == motinova::MessageKind::kKeyword && !m.find("keyword")) {
    append_key(out, first, "keyword");
    append_json_string(out, m.desc->keyword);
  }
  for (const auto& v : m.values()) {
    if (v.field->kind == FieldKind::kReserved) continue;
    append_field(out, first, m, v, options);
  }
  out += '}';
}

void append_message_json(JsonBuffer& out, const motinova::DecodedMessage& m, motinova::Micros ts,
                         const motinova::DecodeOptions& options) {
  const auto& frame = *m.frame;
  out += "{\"ts\":";
  append_ts(out, ts);
  out += ",\"can_id\":";
  append_hex_id(out, frame.can_id, 3);
  out += ",\"src\":";
  append_json_string(out, motinova::node_name(motinova::source_of(frame.can_id)));
  out += ",\"dst\":";
  append_json_string(out, motinova::node_name(motinova::target_of(frame.can_id)));
  out += ",\"mode\":";
  append_json_string(out, motinova::mode_name(frame.mode));
  out += ",\"function\":";
  append_hex_id(out, frame.function, 2);
  out += ",\"message\":";
  append_json_string(out, m.name());
  if (!m.mode_matches) out += ",\"mode_mismatch\":true";
  out += ",\"fields\":";
  append_fields_json(out, m, options);
  out += '}';
}

void append_error_json(JsonBuffer& out, const motinova::ReassemblyErrorEvent& e) {
  out += "{\"ts\":";
  append_ts(out, e.timestamp);
  out += ",\"can_id\":";
  append_hex_id(out, e.can_id, 3);
  out += ",\"error\":";
  append_json_string(out, motinova::reassembly_error_name(e.kind));
  out += ",\"bytes_dropped\":";
  append_int(out, e.bytes_dropped);
  out += '}';
}

}  // namespace fleetgw::decode
