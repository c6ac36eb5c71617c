// JSON text written directly (json_text.h).
#include "backend/ingest/json_text.h"

#include <nlohmann/json.hpp>

#include <charconv>

#include "backend/ingest/safe_text.h"

namespace fleetgw::ingest {

void append_json_string(std::string& out, std::string_view s) {
  if (!is_valid_utf8(s)) {
    out += nlohmann::json(std::string(s)).dump(-1, ' ', false,
                                               nlohmann::json::error_handler_t::replace);
    return;
  }
  out += '"';
  std::size_t run = 0;  // start of the bytes not yet copied
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c != '"' && c != '\\') continue;
    out.append(s.data() + run, i - run);
    run = i + 1;
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\b': out += "\\b"; break;
      case '\f': out += "\\f"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default: {
        static constexpr char kHex[] = "0123456789abcdef";
        out += "\\u00";
        out += kHex[c >> 4];
        out += kHex[c & 0xF];
      }
    }
  }
  out.append(s.data() + run, s.size() - run);
  out += '"';
}

void JsonWriter::number(std::uint64_t v) {
  comma();
  char digits[24];
  const auto r = std::to_chars(digits, digits + sizeof digits, v);
  out_.append(digits, r.ptr);
}

}  // namespace fleetgw::ingest
