// Backoff: the one retry schedule of the gateway's engine. A stage whose run() reported an error
// is not run again before retry_at(); each further failure doubles the wait up to `max`; the
// first success resets it. Stages keep their data and never time their own retries
// (runtime/stage.h).
#pragma once

#include <algorithm>
#include <chrono>
#include <optional>

#include "gateway/runtime/stage.h"

namespace fleetgw::runtime {

class Backoff {
 public:
  using Duration = std::chrono::steady_clock::duration;
  struct Options {
    Duration initial = std::chrono::seconds(1);  // the wait after the first failure
    Duration max = std::chrono::seconds(30);     // the longest wait
  };

  Backoff() = default;
  explicit Backoff(Options options) : options_(options) {}

  // A failure at `now`: returns when the next attempt is due.
  EngineTime failed(EngineTime now) {
    wait_ = failures_ == 0 ? options_.initial : std::min(wait_ * 2, options_.max);
    ++failures_;
    retry_at_ = now + wait_;
    return *retry_at_;
  }
  void succeeded() {
    failures_ = 0;
    retry_at_.reset();
  }
  // True while an attempt at `now` would come too early.
  bool waiting(EngineTime now) const { return retry_at_ && now < *retry_at_; }
  std::optional<EngineTime> retry_at() const { return retry_at_; }
  int failures() const { return failures_; }

 private:
  Options options_;
  Duration wait_{0};
  int failures_ = 0;
  std::optional<EngineTime> retry_at_;
};

}  // namespace fleetgw::runtime
