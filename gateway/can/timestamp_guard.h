// Keeps receive timestamps from running backwards.
//
// Kernel receive timestamps are wall-clock (CLOCK_REALTIME) times, and they do not always
// increase: right after the first socket asks for timestamps the kernel enables receive
// stamping asynchronously, so the first frames may be stamped when they are *read* (later than
// frames stamped on arrival), and NTP/GPS may step the wall clock. Downstream stages (reassembly
// timeouts, ride durations) assume time moves forward.
//
// Contract:
//  * apply(ts) returns ts, except when ts is earlier than the last returned value by at most
//    `max_jitter`: then it returns the last value (frames keep bus order and get a timestamp no
//    earlier than their predecessor) and counts a clamp.
//  * A backward jump larger than max_jitter is taken as the wall clock being set back: ts is
//    returned unchanged (freezing the timeline for that long would be worse) and counted as a
//    clock step.
//  * reset() forgets the history (e.g. after re-opening the socket).
#pragma once

#include <cstdint>
#include <optional>

#include "motinova/can.h"

namespace fleetgw::can {

class TimestampGuard {
 public:
  explicit TimestampGuard(motinova::Micros max_jitter = motinova::Micros{1'000'000})
      : max_jitter_(max_jitter) {}

  motinova::Micros apply(motinova::Micros ts) {
    if (last_ && ts < *last_) {
      if (*last_ - ts <= max_jitter_) {
        ++clamped_;
        return *last_;
      }
      ++clock_steps_;
    }
    last_ = ts;
    return ts;
  }
  void reset() { last_.reset(); }

  uint64_t clamped() const { return clamped_; }
  uint64_t clock_steps() const { return clock_steps_; }

 private:
  motinova::Micros max_jitter_;
  std::optional<motinova::Micros> last_;
  uint64_t clamped_ = 0;
  uint64_t clock_steps_ = 0;
};

}  // namespace fleetgw::can
