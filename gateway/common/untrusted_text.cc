#include "gateway/common/untrusted_text.h"

#include <algorithm>
#include <cstdint>

namespace fleetgw::common {
namespace {

constexpr std::string_view kReplacement = "\xEF\xBF\xBD";  // U+FFFD
constexpr std::string_view kEllipsis = "...";

// One decoded code point: its value, its length in bytes, and whether the bytes were valid.
struct CodePoint {
  std::uint32_t value = 0;
  std::size_t length = 1;
  bool valid = false;
};

bool continuation(unsigned char c) {
  return (c & 0xC0) == 0x80;
}

// Decodes the code point at s[i] strictly (RFC 3629: no overlongs, no surrogates, <= U+10FFFF).
// An invalid sequence reports length 1 so decoding resumes at the next byte.
CodePoint decode(std::string_view s, std::size_t i) {
  const auto at = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char b0 = at(0);
  const std::size_t left = s.size() - i;
  if (b0 < 0x80) return {b0, 1, true};
  std::size_t n = 0;
  unsigned char lo = 0x80;
  unsigned char hi = 0xBF;
  if (b0 >= 0xC2 && b0 <= 0xDF) {
    n = 2;
  } else if (b0 >= 0xE0 && b0 <= 0xEF) {
    n = 3;
    if (b0 == 0xE0) lo = 0xA0;  // overlong
    if (b0 == 0xED) hi = 0x9F;  // surrogates
  } else if (b0 >= 0xF0 && b0 <= 0xF4) {
    n = 4;
    if (b0 == 0xF0) lo = 0x90;  // overlong
    if (b0 == 0xF4) hi = 0x8F;  // above U+10FFFF
  } else {
    return {};
  }
  if (left < n || at(1) < lo || at(1) > hi) return {};
  for (std::size_t k = 2; k < n; ++k) {
    if (!continuation(at(k))) return {};
  }
  std::uint32_t v = b0 & (0xFF >> (n + 1));
  for (std::size_t k = 1; k < n; ++k) v = (v << 6) | (at(k) & 0x3F);
  return {v, n, true};
}

void append_hex(std::string& out, std::uint32_t v, int digits) {
  static constexpr char kDigits[] = "0123456789abcdef";
  for (int shift = (digits - 1) * 4; shift >= 0; shift -= 4) out += kDigits[(v >> shift) & 0xF];
}

// The escaped form of the code point at s[i] (valid UTF-8 or U+FFFD), appended to `out`.
void append_escaped(std::string& out, std::string_view s, const CodePoint& cp, std::size_t i) {
  if (!cp.valid) {
    out += kReplacement;
    return;
  }
  const std::uint32_t v = cp.value;
  if (v == '\\') {
    out += "\\\\";
  } else if (v == '\n') {
    out += "\\n";
  } else if (v == '\r') {
    out += "\\r";
  } else if (v == '\t') {
    out += "\\t";
  } else if (v < 0x20 || v == 0x7F) {
    out += "\\x";
    append_hex(out, v, 2);
  } else if ((v >= 0x80 && v <= 0x9F) || v == 0x2028 || v == 0x2029) {
    out += "\\u{";
    append_hex(out, v, 4);
    out += '}';
  } else {
    out.append(s.substr(i, cp.length));
  }
}

}  // namespace

bool is_valid_utf8(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const CodePoint cp = decode(s, i);
    if (!cp.valid) return false;
    i += cp.length;
  }
  return true;
}

std::string valid_utf8(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const CodePoint cp = decode(s, i);
    if (cp.valid) {
      out.append(s.substr(i, cp.length));
    } else {
      out += kReplacement;
    }
    i += cp.length;
  }
  return out;
}

std::string truncate_utf8(std::string_view s, std::size_t max_bytes) {
  std::string out;
  out.reserve(std::min(s.size(), max_bytes));
  for (std::size_t i = 0; i < s.size();) {
    const CodePoint cp = decode(s, i);
    const std::string_view piece = cp.valid ? s.substr(i, cp.length) : kReplacement;
    if (out.size() + piece.size() > max_bytes) break;
    out.append(piece);
    i += cp.length;
  }
  return out;
}

std::string escape_controls(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const CodePoint cp = decode(s, i);
    append_escaped(out, s, cp, i);
    i += cp.length;
  }
  return out;
}

std::string untrusted_excerpt(std::string_view s, std::size_t max_bytes) {
  std::string out;
  out.reserve(std::min(s.size(), max_bytes));
  // Room kept for the ellipsis once we know the text does not fit.
  const std::size_t budget = max_bytes >= kEllipsis.size() ? max_bytes - kEllipsis.size() : 0;
  std::size_t fitting = 0;  // length of `out` when it last fitted within `budget`
  std::string piece;
  for (std::size_t i = 0; i < s.size();) {
    const CodePoint cp = decode(s, i);
    piece.clear();
    append_escaped(piece, s, cp, i);
    if (out.size() + piece.size() > max_bytes) {
      out.resize(fitting);
      if (max_bytes >= kEllipsis.size()) out += kEllipsis;
      return out;
    }
    out += piece;
    if (out.size() <= budget) fitting = out.size();
    i += cp.length;
  }
  return out;
}

}  // namespace fleetgw::common
