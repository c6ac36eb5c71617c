// TimedWork: the timed part of a transport -- re-opening an interface that went away, retrying
// a driver queue that was full -- done when the gateway's engine says, never on a timer of the
// transport's own. The runtime turns it into a stage (runtime/stages.h, TransportStage); the
// engine's one timer and its one back-off (runtime/backoff.h) schedule it. gateway/can/ does
// not depend on the runtime: this is all it sees of it.
//
// Contract:
//  * next_deadline(): the earliest Env::steady_now() time at which poll() has due work, or
//    none. It may be "now" while an attempt is due (the engine's back-off holds it back after
//    a failure).
//  * poll(now): does what is due at `now` and returns the failure text of an attempt that
//    failed (the interface still down); the caller retries with its back-off, after which
//    next_deadline() says the attempt is due again. A loss of the link (noticed on the loop,
//    outside poll()) is reported by the next poll() as its failure, so the first re-open waits
//    the back-off too.
//  * `wake` (set by the owner before start()) is called, on the loop's thread, when
//    next_deadline() moved earlier outside poll() (a lost link, a full driver queue), so the
//    owner re-reads it.
//  * Single-threaded, on the transport's io_context thread.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>

#include "env/env.h"

namespace fleetgw::can {

class TimedWork {
 public:
  using Time = Env::SteadyTime;
  virtual ~TimedWork() = default;
  virtual std::optional<Time> next_deadline() const = 0;
  virtual std::optional<std::string> poll(Time now) = 0;
  // How the owner spaces attempts after a failed poll(): `initial` after the first failure,
  // doubling up to `max` (the engine's Backoff::Options).
  struct RetrySpacing {
    std::chrono::steady_clock::duration initial;
    std::chrono::steady_clock::duration max;
  };
  virtual RetrySpacing retry_spacing() const = 0;
  void set_wake(std::function<void()> wake) { wake_ = std::move(wake); }

 protected:
  void wake() const {
    if (wake_) wake_();
  }

 private:
  std::function<void()> wake_;
};

}  // namespace fleetgw::can
