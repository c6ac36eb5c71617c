#include "gateway/runtime/engine.h"

#include <spdlog/spdlog.h>

#include <asio/post.hpp>

namespace fleetgw::runtime {

Engine::Engine(asio::io_context& io, Env& env) : io_(io), env_(env), timer_(io) {}

Engine::~Engine() {
  alive_.reset();
}

void Engine::add(Stage& stage, Route route, Backoff::Options backoff) {
  entries_.push_back(Entry{&stage, std::move(route), Backoff(backoff), {}});
}

const Backoff* Engine::backoff(const Stage& stage) const {
  for (const auto& e : entries_) {
    if (e.stage == &stage) return &e.backoff;
  }
  return nullptr;
}

void Engine::request_settle() {
  if (settling_) {
    settle_again_ = true;  // the running settle() loops again
    return;
  }
  if (settle_posted_ || stopped_) return;
  settle_posted_ = true;
  asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
    if (token.expired()) return;
    settle_posted_ = false;
    settle();
  });
}

void Engine::wake() {
  if (wake_posted_.exchange(true)) return;
  asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
    if (token.expired()) return;
    wake_posted_.store(false);
    settle();
  });
}

void Engine::settle() {
  if (settling_ || stopped_) return;
  settling_ = true;
  ++counters_.settles;
  bool more = false;
  for (int round = 0; round < kMaxSettleRounds; ++round) {
    more = false;
    settle_again_ = false;
    const EngineTime now = env_.steady_now();
    for (auto& e : entries_) {
      if (e.backoff.waiting(now)) continue;
      const StageRun r = e.stage->run(now);
      if (stopped_) break;
      if (!r.ok()) {
        ++counters_.failures;
        const auto at = e.backoff.failed(now);
        if (r.status.message != e.last_error) {
          spdlog::warn("{}: {} (retried in {} ms)", e.stage->name(), r.status.message,
                       std::chrono::duration_cast<std::chrono::milliseconds>(at - now).count());
          e.last_error = r.status.message;
        }
      } else if (e.backoff.failures() > 0) {
        e.backoff.succeeded();
        e.last_error.clear();
      }
      if (r.produced > 0) more = true;
      if (e.route && e.route()) more = true;
      if (stopped_) break;
    }
    timer_turn_ = false;
    if (stopped_) break;
    if (!more && !settle_again_) break;
  }
  settling_ = false;
  if (stopped_) return;
  if (after_settle_) after_settle_();
  if (stopped_) return;
  // The round bound was reached with work left: the next loop turn goes on.
  if (more || settle_again_) request_settle();
  arm();
}

void Engine::arm() {
  if (stopped_) return;
  std::optional<EngineTime> at;
  for (const auto& e : entries_) {
    const auto t = e.backoff.retry_at() ? e.backoff.retry_at() : e.stage->next_deadline();
    if (t && (!at || *t < *at)) at = t;
  }
  if (!at) {
    if (armed_for_) timer_.cancel();
    armed_for_.reset();
    return;
  }
  if (armed_for_ && *armed_for_ == *at) return;
  armed_for_ = at;
  // Relative to the Env's clock, so an injected clock arms the same wait.
  timer_.expires_after(*at - env_.steady_now());
  timer_.async_wait([this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
    // A cancelled wait (re-armed or stopped) does nothing: the new wait is already pending.
    if (ec || token.expired() || stopped_) return;
    armed_for_.reset();
    on_timer();
  });
}

void Engine::on_timer() {
  ++counters_.timer_wakeups;
  timer_turn_ = true;
  settle();
  timer_turn_ = false;
}

void Engine::stop() {
  if (stopped_) return;
  stopped_ = true;
  timer_.cancel();
  armed_for_.reset();
}

}  // namespace fleetgw::runtime
