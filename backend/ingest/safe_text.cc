// Untrusted text helpers (safe_text.h).
#include "backend/ingest/safe_text.h"

#include <cstdint>

namespace fleetgw::ingest {
namespace {

constexpr std::string_view kReplacement = "\xEF\xBF\xBD";  // U+FFFD

// Length of the valid UTF-8 sequence at s[i] (RFC 3629), 0 when it is not one.
std::size_t sequence_length(std::string_view s, std::size_t i) {
  const auto at = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char b0 = at(0);
  if (b0 < 0x80) return 1;
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
    return 0;
  }
  if (s.size() - i < n || at(1) < lo || at(1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k) {
    if ((at(k) & 0xC0) != 0x80) return 0;
  }
  return n;
}

// The printable form of the code point at s[i] (length n, 0 = invalid byte).
std::string piece(std::string_view s, std::size_t i, std::size_t n, bool escape) {
  if (n == 0) return std::string(kReplacement);
  const unsigned char c = static_cast<unsigned char>(s[i]);
  if (escape && n == 1) {
    if (c == '\\') return "\\\\";
    if (c == '\n') return "\\n";
    if (c == '\r') return "\\r";
    if (c == '\t') return "\\t";
    if (c < 0x20 || c == 0x7F) {
      static constexpr char kHex[] = "0123456789abcdef";
      return std::string{'\\', 'x', kHex[c >> 4], kHex[c & 0xF]};
    }
  }
  return std::string(s.substr(i, n));
}

}  // namespace

bool is_valid_utf8(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = sequence_length(s, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string truncate_utf8(std::string_view s, std::size_t max_bytes) {
  std::string out;
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = sequence_length(s, i);
    const std::string p = piece(s, i, n, false);
    if (out.size() + p.size() > max_bytes) break;
    out += p;
    i += n == 0 ? 1 : n;
  }
  return out;
}

std::string untrusted_excerpt(std::string_view s, std::size_t max_bytes) {
  constexpr std::string_view kEllipsis = "...";
  const std::size_t budget = max_bytes >= kEllipsis.size() ? max_bytes - kEllipsis.size() : 0;
  std::string out;
  std::size_t fitting = 0;  // length of `out` when it last fitted within `budget`
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = sequence_length(s, i);
    const std::string p = piece(s, i, n, true);
    if (out.size() + p.size() > max_bytes) {
      out.resize(fitting);
      if (max_bytes >= kEllipsis.size()) out += kEllipsis;
      return out;
    }
    out += p;
    if (out.size() <= budget) fitting = out.size();
    i += n == 0 ? 1 : n;
  }
  return out;
}

}  // namespace fleetgw::ingest
