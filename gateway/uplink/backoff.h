// Reconnect back-off: exponential growth with jitter, so a fleet of vehicles that lost the
// broker at the same moment does not reconnect in lock-step.
//
// Contract: next() returns the wait before the next attempt after one more consecutive failure:
// uniformly random in [d/2, d], d = min(max, min * 2^failures_so_far). reset() after a
// successful connection. Deterministic for a given seed (tests); no clock, no global state.
#pragma once

#include <chrono>
#include <cstdint>
#include <random>

namespace fleetgw::uplink {

class Backoff {
 public:
  Backoff(std::chrono::milliseconds min, std::chrono::milliseconds max, std::uint64_t seed);

  std::chrono::milliseconds next();
  void reset() { failures_ = 0; }
  unsigned failures() const { return failures_; }

 private:
  std::chrono::milliseconds min_, max_;
  unsigned failures_ = 0;
  std::mt19937_64 rng_;
};

}  // namespace fleetgw::uplink
