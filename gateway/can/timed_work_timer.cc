#include "gateway/can/timed_work_timer.h"

namespace fleetgw::can {
namespace {

Backoff::Options spacing_of(const TimedWork& work) {
  const auto s = work.retry_spacing();
  return {.initial = s.initial, .max = s.max};
}

}  // namespace

TimedWorkTimer::TimedWorkTimer(asio::io_context& io, TimedWork& work, Env& env)
    : timer_(io), work_(work), env_(env), backoff_(spacing_of(work)) {}

TimedWorkTimer::~TimedWorkTimer() {
  stop();
}

void TimedWorkTimer::start() {
  work_.set_wake([this, token = std::weak_ptr<int>(alive_)] {
    if (!token.expired()) arm();
  });
  arm();
}

void TimedWorkTimer::stop() {
  if (stopped_) return;
  stopped_ = true;
  alive_.reset();
  work_.set_wake({});
  timer_.cancel();
}

void TimedWorkTimer::arm() {
  if (stopped_) return;
  const auto at = backoff_.retry_at() ? backoff_.retry_at() : work_.next_deadline();
  if (!at) {
    timer_.cancel();
    return;
  }
  // Re-arming cancels the wait already pending (its handler sees operation_aborted).
  timer_.expires_after(*at - env_.steady_now());
  timer_.async_wait([this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
    if (ec || token.expired() || stopped_) return;
    fire();
  });
}

void TimedWorkTimer::fire() {
  const auto now = env_.steady_now();
  if (!backoff_.waiting(now)) {
    if (work_.poll(now)) {
      backoff_.failed(now);
    } else if (backoff_.failures() > 0) {
      backoff_.succeeded();
    }
    if (stopped_) return;
  }
  arm();
}

}  // namespace fleetgw::can
