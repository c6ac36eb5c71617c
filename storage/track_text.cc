#include "storage/track_text.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>

namespace fleetgw::storage {
namespace {

// A coordinate as the decimal of its value rounded to 1e-7, from integer arithmetic so the
// text is exact and locale-independent ("13.405", "-0.0000001", "52").
void append_e7(std::string& out, double deg) {
  const auto e7 = static_cast<std::int64_t>(std::llround(deg * 1e7));
  if (e7 < 0) out += '-';
  const std::uint64_t magnitude =
      e7 < 0 ? static_cast<std::uint64_t>(-(e7 + 1)) + 1 : static_cast<std::uint64_t>(e7);
  out += std::to_string(magnitude / 10'000'000);
  std::uint64_t frac = magnitude % 10'000'000;
  if (frac == 0) return;
  std::string digits = std::to_string(frac);
  digits.insert(0, 7 - digits.size(), '0');
  while (digits.back() == '0') digits.pop_back();
  out += '.';
  out += digits;
}

}  // namespace

std::string track_text(std::span<const TrackPoint> points) {
  std::string out = "[";
  out.reserve(2 + points.size() * 24);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i > 0) out += ',';
    out += '[';
    append_e7(out, points[i].lon_deg);
    out += ',';
    append_e7(out, points[i].lat_deg);
    out += ']';
  }
  out += ']';
  return out;
}

ParsedTrack parse_track_text(std::string_view text) {
  ParsedTrack result;
  const auto doc = nlohmann::json::parse(text, nullptr, false);
  if (doc.is_discarded()) {
    result.error = "not valid JSON";
    return result;
  }
  if (!doc.is_array()) {
    result.error = "not a JSON array of [longitude, latitude] positions";
    return result;
  }
  result.points.reserve(doc.size());
  for (std::size_t i = 0; i < doc.size(); ++i) {
    const auto& p = doc[i];
    const std::string where = "position " + std::to_string(i) + ": ";
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
      result.error = where + "not an array of two numbers [longitude, latitude]";
      break;
    }
    const double lon = p[0].get<double>();
    const double lat = p[1].get<double>();
    if (!std::isfinite(lon) || std::fabs(lon) > 180.0) {
      result.error = where + "longitude " + p[0].dump() + " is outside -180..180";
      break;
    }
    if (!std::isfinite(lat) || std::fabs(lat) > 90.0) {
      result.error = where + "latitude " + p[1].dump() + " is outside -90..90";
      break;
    }
    result.points.push_back({lat, lon});
  }
  if (!result.ok()) result.points.clear();
  return result;
}

}  // namespace fleetgw::storage
