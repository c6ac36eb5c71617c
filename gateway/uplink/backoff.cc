#include "gateway/uplink/backoff.h"

#include <algorithm>
#include <stdexcept>

namespace fleetgw::uplink {

Backoff::Backoff(std::chrono::milliseconds min, std::chrono::milliseconds max, std::uint64_t seed)
    : min_(min), max_(max), rng_(seed) {
  if (min_.count() <= 0 || max_ < min_) {
    throw std::invalid_argument("back-off needs 0 < min <= max");
  }
}

std::chrono::milliseconds Backoff::next() {
  // Double per failure, saturating; the shift is capped so it cannot overflow.
  std::int64_t d = min_.count();
  for (unsigned i = 0; i < failures_ && d < max_.count(); ++i) d *= 2;
  d = std::min<std::int64_t>(d, max_.count());
  if (failures_ < 64) ++failures_;
  std::uniform_int_distribution<std::int64_t> jitter(d / 2, d);
  return std::chrono::milliseconds(jitter(rng_));
}

}  // namespace fleetgw::uplink
