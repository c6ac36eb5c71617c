#include "gateway/tools/common/time_arg.h"

#include <fmt/format.h>

#include <chrono>
#include <limits>

namespace fleetgw::tools {
namespace {

using std::chrono::days;
using std::chrono::sys_days;

constexpr std::int64_t kUsPerSecond = 1'000'000;

// Reads exactly `n` decimal digits at `pos`.
std::optional<int> fixed_digits(std::string_view s, std::size_t& pos, std::size_t n) {
  if (pos + n > s.size()) return std::nullopt;
  int value = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const char c = s[pos + i];
    if (c < '0' || c > '9') return std::nullopt;
    value = value * 10 + (c - '0');
  }
  pos += n;
  return value;
}

bool all_digits(std::string_view s) {
  if (s.empty()) return false;
  for (const char c : s) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

// Digits only, as a non-negative int64 (nullopt on overflow).
std::optional<std::int64_t> to_int64(std::string_view s) {
  if (!all_digits(s)) return std::nullopt;
  std::int64_t v = 0;
  for (const char c : s) {
    const int d = c - '0';
    if (v > (std::numeric_limits<std::int64_t>::max() - d) / 10) return std::nullopt;
    v = v * 10 + d;
  }
  return v;
}

std::optional<std::int64_t> parse_relative(std::string_view s, std::int64_t now_us) {
  if (s.size() < 2) return std::nullopt;
  std::int64_t unit_s = 0;
  switch (s.back()) {
    case 's':
      unit_s = 1;
      break;
    case 'm':
      unit_s = 60;
      break;
    case 'h':
      unit_s = 3600;
      break;
    case 'd':
      unit_s = 86400;
      break;
    default:
      return std::nullopt;
  }
  const auto n = to_int64(s.substr(0, s.size() - 1));
  const std::int64_t per = unit_s * kUsPerSecond;
  if (!n || *n > std::numeric_limits<std::int64_t>::max() / per) return std::nullopt;
  const std::int64_t back = *n * per;
  if (now_us < std::numeric_limits<std::int64_t>::min() + back) return std::nullopt;
  return now_us - back;
}

std::optional<std::int64_t> parse_iso(std::string_view s) {
  std::size_t pos = 0;
  const auto y = fixed_digits(s, pos, 4);
  if (!y || pos >= s.size() || s[pos++] != '-') return std::nullopt;
  const auto mo = fixed_digits(s, pos, 2);
  if (!mo || pos >= s.size() || s[pos++] != '-') return std::nullopt;
  const auto d = fixed_digits(s, pos, 2);
  if (!d) return std::nullopt;
  const std::chrono::year_month_day ymd{std::chrono::year{*y},
                                        std::chrono::month{static_cast<unsigned>(*mo)},
                                        std::chrono::day{static_cast<unsigned>(*d)}};
  if (!ymd.ok()) return std::nullopt;
  std::int64_t seconds = sys_days{ymd}.time_since_epoch().count() * std::int64_t{86400};
  if (pos == s.size()) return seconds * kUsPerSecond;  // a date alone: midnight UTC

  if (s[pos] != 'T' && s[pos] != 't' && s[pos] != ' ') return std::nullopt;
  ++pos;
  const auto hh = fixed_digits(s, pos, 2);
  if (!hh || *hh > 23 || pos >= s.size() || s[pos++] != ':') return std::nullopt;
  const auto mm = fixed_digits(s, pos, 2);
  if (!mm || *mm > 59) return std::nullopt;
  int ss = 0;
  std::int64_t fraction_us = 0;
  if (pos < s.size() && s[pos] == ':') {
    ++pos;
    const auto sec = fixed_digits(s, pos, 2);
    if (!sec || *sec > 59) return std::nullopt;
    ss = *sec;
    if (pos < s.size() && (s[pos] == '.' || s[pos] == ',')) {
      ++pos;
      std::int64_t scale = 100'000;
      std::size_t digits = 0;
      while (pos < s.size() && s[pos] >= '0' && s[pos] <= '9') {
        if (++digits > 6) return std::nullopt;
        fraction_us += (s[pos] - '0') * scale;
        scale /= 10;
        ++pos;
      }
      if (digits == 0) return std::nullopt;
    }
  }
  seconds += *hh * 3600 + *mm * 60 + ss;
  if (pos < s.size()) {
    if (s[pos] == 'Z' || s[pos] == 'z') {
      ++pos;
    } else if (s[pos] == '+' || s[pos] == '-') {
      const int sign = s[pos++] == '+' ? 1 : -1;
      const auto oh = fixed_digits(s, pos, 2);
      if (!oh || *oh > 23) return std::nullopt;
      if (pos < s.size() && s[pos] == ':') ++pos;
      const auto om = fixed_digits(s, pos, 2);
      if (!om || *om > 59) return std::nullopt;
      // 10:00+02:00 is 08:00 UTC.
      seconds -= sign * (*oh * 3600 + *om * 60);
    } else {
      return std::nullopt;
    }
  }
  if (pos != s.size()) return std::nullopt;
  return seconds * kUsPerSecond + fraction_us;
}

}  // namespace

std::optional<std::int64_t> parse_since(std::string_view text, std::int64_t now_us) {
  if (text.empty()) return std::nullopt;
  if (all_digits(text)) return to_int64(text);
  if (const auto rel = parse_relative(text, now_us)) return rel;
  return parse_iso(text);
}

std::string iso_utc(std::int64_t us) {
  const std::chrono::sys_time<std::chrono::microseconds> tp{std::chrono::microseconds{us}};
  const auto day = std::chrono::floor<days>(tp);
  const std::chrono::year_month_day ymd{day};
  const std::chrono::hh_mm_ss hms{std::chrono::floor<std::chrono::seconds>(tp - day)};
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}Z", static_cast<int>(ymd.year()),
                     static_cast<unsigned>(ymd.month()), static_cast<unsigned>(ymd.day()),
                     hms.hours().count(), hms.minutes().count(), hms.seconds().count());
}

std::int64_t wall_clock_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace fleetgw::tools
