// Engine: the event loop of `fleetgw run`. It owns the ONE timer, the settle loop, the wake-up
// from other threads and the retry schedule of every stage (runtime/stage.h states the contract
// the stages keep; the Pipeline builds the stages and declares the routes between them).
//
// Contract:
//  * Stages run in the order they were added, each settle round: run(now) on every stage that
//    is not backing off, then the stage's route (the wiring that moves its outputs into other
//    stages' inputs). A round in which no stage produced and no route moved anything ends the
//    settle; at most kMaxSettleRounds rounds run in one loop turn, the rest in the next (posted).
//  * settle() is never re-entered: request_settle() inside a settle only makes it loop again.
//  * The timer is armed on Env::steady_now() for the earliest next_deadline() of the stages
//    (a backing-off stage: its retry time instead). A timer turn is a settle whose first round
//    says so (timer_turn()): stages whose deadlines live on another clock (the simulated bus)
//    act on it.
//  * A failed run (StageRun::status not ok) is logged once per distinct message and retried by the
//    engine with the stage's Backoff (runtime/backoff.h); the first success resets it.
//  * wake() may be called from any thread (Paho, gpsd): it posts one settle to the loop, and
//    coalesces with a wake-up already posted.
//  * stop() cancels the timer; nothing runs after it. The engine's posted handlers check a
//    token, so the engine may be destroyed with handlers still queued in the io_context.
#pragma once

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "env/env.h"
#include "gateway/runtime/backoff.h"
#include "gateway/runtime/stage.h"

namespace fleetgw::runtime {

struct EngineCounters {
  std::uint64_t settles = 0;        // settle() runs
  std::uint64_t timer_wakeups = 0;  // timer expiries handled
  std::uint64_t failures = 0;       // failed StageRuns
};

class Engine {
 public:
  static constexpr int kMaxSettleRounds = 16;
  // Moves a stage's outputs into other stages' inputs; true when it moved anything.
  using Route = std::function<bool()>;

  Engine(asio::io_context& io, Env& env);
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  // `stage` must outlive the engine's use of it (until stop()).
  void add(Stage& stage, Route route = {}, Backoff::Options backoff = {});
  // Runs after every settle (stop conditions, checkpoints): may call stop().
  void set_after_settle(std::function<void()> hook) { after_settle_ = std::move(hook); }

  // On the loop's thread: a stage has new input; settle in this loop turn (or loop again).
  void request_settle();
  // From any thread: post one settle.
  void wake();
  // A deadline may have moved earlier outside a settle (a frame): re-arm the timer.
  void rearm() { arm(); }
  void stop();

  bool stopped() const { return stopped_; }
  bool armed() const { return armed_for_.has_value(); }
  bool timer_turn() const { return timer_turn_; }
  EngineTime now() const { return env_.steady_now(); }
  Env& env() const { return env_; }
  const EngineCounters& counters() const { return counters_; }
  // The retry state of `stage` (nullptr: not added). The pointer stays valid for the engine's
  // life, also while more stages are added (the pipeline keeps the recorder's).
  const Backoff* backoff(const Stage& stage) const;

 private:
  struct Entry {
    Stage* stage;
    Route route;
    Backoff backoff;
    std::string last_error;  // logged once per distinct message
  };

  void settle();
  void arm();
  void on_timer();

  asio::io_context& io_;
  Env& env_;
  asio::steady_timer timer_;
  // A deque: add() never moves the entries, so a backoff() pointer handed out earlier stays
  // valid (a vector's growth freed it: ASan caught the pipeline reading the recorder's retry
  // state after the uplink's stage was added).
  std::deque<Entry> entries_;
  std::function<void()> after_settle_;
  std::optional<EngineTime> armed_for_;
  std::atomic<bool> wake_posted_{false};
  bool settle_posted_ = false;
  bool settling_ = false;
  bool settle_again_ = false;
  bool stopped_ = false;
  bool timer_turn_ = false;
  EngineCounters counters_;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);  // guards posted handlers
};

}  // namespace fleetgw::runtime
