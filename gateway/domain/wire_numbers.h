// Wire numbers: a measured double turned into a protobuf integer field. One rule for every payload:
// rounded to the nearest integer, clamped to the field's range, and 0 for NaN or infinity (a
// decoder's garbage never becomes an undefined conversion).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace fleetgw::domain::wire {

template <typename Int>
Int to_int(double v) {
  if (!std::isfinite(v)) return 0;
  const double lo = static_cast<double>(std::numeric_limits<Int>::min());
  const double hi = static_cast<double>(std::numeric_limits<Int>::max());
  return static_cast<Int>(std::clamp(std::round(v), lo, hi));
}
inline std::uint32_t u32(double v) {
  return to_int<std::uint32_t>(v);
}
inline std::uint64_t u64(double v) {
  return to_int<std::uint64_t>(v);
}
inline std::int32_t s32(double v) {
  return to_int<std::int32_t>(v);
}

}  // namespace fleetgw::domain::wire
