// Backoff: the one retry schedule of the gateway, on the Env's steady clock. The engine keeps
// one per stage (a stage whose run() reported an error is not run again before retry_at();
// runtime/engine.h); the few retries outside any stage use the same class (StoreOutbox's
// deletes, can::TimedWorkTimer for programs without the engine). Each further failure doubles
// the wait up to `max`; the first success resets it. It only computes times: whoever holds it
// reads the clock and arms the timer.
#pragma once

#include <algorithm>
#include <chrono>
#include <optional>

#include "env/env.h"

namespace fleetgw {

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
  Env::SteadyTime failed(Env::SteadyTime now) {
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
  bool waiting(Env::SteadyTime now) const { return retry_at_ && now < *retry_at_; }
  std::optional<Env::SteadyTime> retry_at() const { return retry_at_; }
  int failures() const { return failures_; }

 private:
  Options options_;
  Duration wait_{0};
  int failures_ = 0;
  std::optional<Env::SteadyTime> retry_at_;
};

}  // namespace fleetgw
