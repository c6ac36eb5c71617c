// The engine's contract (gateway/runtime/engine.h): stages run in order and routes move their
// outputs until nothing moves, a settle is never re-entered and is bounded, a failed run is
// retried by the engine's one back-off (never earlier), other threads only wake it, and its one
// timer fires for the earliest deadline. BusClock converts the bus timeline in one place.
#include <gtest/gtest.h>

#include <asio/io_context.hpp>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "env/env.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/engine.h"

namespace fleetgw::runtime {
namespace {

using namespace std::chrono_literals;

// A stage whose behaviour the test scripts.
class ScriptStage final : public Stage {
 public:
  ScriptStage(std::string name, std::vector<std::string>& log)
      : name_(std::move(name)), log_(log) {}
  std::string_view name() const override { return name_; }
  std::optional<EngineTime> next_deadline() const override { return deadline; }
  StageRun run(EngineTime) override {
    log_.push_back(name_);
    ++runs;
    if (fail) return {.produced = 0, .status = Status::error(StatusCode::kFull, "disk full")};
    if (on_run) on_run();
    std::size_t produced = 0;
    if (inbox > 0) {
      outbox += inbox;
      produced = inbox;
      inbox = 0;
    }
    if (always_produce) produced = 1;
    return {.produced = produced, .status = {}};
  }

  int inbox = 0;
  int outbox = 0;
  int runs = 0;
  bool fail = false;
  bool always_produce = false;
  std::optional<EngineTime> deadline;
  std::function<void()> on_run;

 private:
  std::string name_;
  std::vector<std::string>& log_;
};

TEST(Engine, RunsStagesInOrderAndRoutesUntilNothingMoves) {
  asio::io_context io;
  ManualEnv env;
  Engine engine(io, env);
  std::vector<std::string> log;
  ScriptStage a("a", log), b("b", log);
  a.inbox = 2;
  // a's outputs become b's inputs; b's run comes after a's in the same round.
  engine.add(a, [&] {
    if (a.outbox == 0) return false;
    b.inbox += std::exchange(a.outbox, 0);
    return true;
  });
  engine.add(b);
  engine.request_settle();
  io.poll();
  EXPECT_EQ(b.outbox, 2);
  // Round 1: a produced (and routed), b produced; round 2: nothing moved -> done.
  EXPECT_EQ(log, (std::vector<std::string>{"a", "b", "a", "b"}));
  EXPECT_EQ(engine.counters().settles, 1u);
}

TEST(Engine, IsNeverReenteredAndBoundsOneLoopTurn) {
  asio::io_context io;
  ManualEnv env;
  Engine engine(io, env);
  std::vector<std::string> log;
  ScriptStage a("a", log);
  int depth = 0, max_depth = 0;
  a.on_run = [&] {
    max_depth = std::max(max_depth, ++depth);
    engine.request_settle();  // inside a settle: loops again, never recurses
    --depth;
  };
  a.always_produce = true;
  engine.add(a);
  engine.request_settle();
  io.run_one();
  EXPECT_EQ(max_depth, 1);
  EXPECT_EQ(a.runs, Engine::kMaxSettleRounds);
  // The rest goes on in the next loop turn.
  a.always_produce = false;
  a.on_run = nullptr;
  io.poll();
  EXPECT_EQ(engine.counters().settles, 2u);
}

TEST(Engine, RetriesAFailedStageWithItsBackoffNeverEarlier) {
  asio::io_context io;
  ManualEnv env;
  Engine engine(io, env);
  std::vector<std::string> log;
  ScriptStage store("store", log), after("after", log);
  store.fail = true;
  engine.add(store, {}, Backoff::Options{.initial = 1s, .max = 4s});
  engine.add(after);
  const EngineTime t0 = env.steady_now();
  engine.request_settle();
  io.poll();
  EXPECT_EQ(store.runs, 1);
  EXPECT_EQ(after.runs, 1) << "a failing stage does not hold up the others";
  ASSERT_NE(engine.backoff(store), nullptr);
  EXPECT_EQ(engine.backoff(store)->retry_at(), t0 + 1s);
  // Asked again before its retry time: not run.
  env.advance(999ms);
  engine.request_settle();
  io.poll();
  EXPECT_EQ(store.runs, 1);
  env.advance(1ms);
  engine.request_settle();
  io.poll();
  EXPECT_EQ(store.runs, 2);
  EXPECT_EQ(engine.backoff(store)->retry_at(), t0 + 1s + 2s) << "the wait doubles";
  env.advance(2s);
  store.fail = false;
  engine.request_settle();
  io.poll();
  EXPECT_EQ(store.runs, 3);
  EXPECT_EQ(engine.backoff(store)->failures(), 0) << "a success resets the back-off";
  EXPECT_FALSE(engine.backoff(store)->retry_at());
  EXPECT_EQ(engine.counters().failures, 2u);
}

// The pipeline keeps the recorder's retry state from backoff() and adds the uplink's stage after
// it: the pointer must keep showing the live state however many stages come later (it once
// pointed into a vector that the next add() reallocated).
TEST(Engine, ABackoffHandedOutStaysTheStagesLiveStateAsMoreStagesAreAdded) {
  asio::io_context io;
  ManualEnv env;
  Engine engine(io, env);
  std::vector<std::string> log;
  ScriptStage store("store", log);
  store.fail = true;
  engine.add(store, {}, Backoff::Options{.initial = 1s, .max = 4s});
  const Backoff* kept = engine.backoff(store);
  ASSERT_NE(kept, nullptr);
  std::vector<std::unique_ptr<ScriptStage>> more;
  for (int i = 0; i < 64; ++i) {
    more.push_back(std::make_unique<ScriptStage>("s" + std::to_string(i), log));
    engine.add(*more.back());
  }
  EXPECT_EQ(kept, engine.backoff(store)) << "the entry moved when stages were added";
  engine.request_settle();
  io.poll();
  EXPECT_EQ(store.runs, 1);
  EXPECT_TRUE(kept->waiting(env.steady_now())) << "the kept pointer misses the failure";
  EXPECT_EQ(kept->failures(), 1);
}

TEST(Engine, TimerFiresForTheEarliestDeadlineAsATimerTurn) {
  asio::io_context io;
  Engine engine(io, Env::system());
  std::vector<std::string> log;
  ScriptStage late("late", log), soon("soon", log);
  bool timer_turn_seen = false;
  soon.on_run = [&] {
    if (engine.timer_turn()) {
      timer_turn_seen = true;
      soon.deadline.reset();
      late.deadline.reset();
      engine.stop();
    }
  };
  late.deadline = Env::system().steady_now() + 60s;
  soon.deadline = Env::system().steady_now() + 20ms;
  engine.add(late);
  engine.add(soon);
  engine.rearm();
  EXPECT_TRUE(engine.armed());
  io.run_for(30s);  // ends when the stopped engine leaves nothing pending
  EXPECT_TRUE(timer_turn_seen);
  EXPECT_EQ(engine.counters().timer_wakeups, 1u);
}

TEST(Engine, AnotherThreadOnlyWakesIt) {
  asio::io_context io;
  ManualEnv env;
  Engine engine(io, env);
  std::vector<std::string> log;
  ScriptStage a("a", log);
  engine.add(a);
  std::thread t([&] {
    engine.wake();
    engine.wake();
  });
  t.join();
  EXPECT_EQ(a.runs, 0) << "nothing runs on the waking thread";
  io.poll();
  EXPECT_EQ(a.runs, 1) << "two wake-ups before the loop ran: one settle";
}

TEST(BusClock, ConvertsEachTimelineToEngineTimeInOnePlace) {
  ManualEnv env;
  using motinova::Micros;
  // The simulator at 10x: one second of bus time ahead is 100 ms of engine time.
  Micros virtual_now{5'000'000};
  auto sim = BusClock::simulated(
      env, [&] { return virtual_now; }, 10.0);
  EXPECT_EQ(sim.now(), virtual_now) << "before the first frame: the simulator's clock";
  EXPECT_EQ(sim.to_engine(Micros(6'000'000)), env.steady_now() + 100ms);
  EXPECT_EQ(sim.to_engine(Micros(4'000'000)), env.steady_now() + BusClock::kMinSimWait);
  sim.on_frame(Micros(4'500'000));
  EXPECT_EQ(sim.now(), Micros(4'500'000)) << "frames delivered are the clock";
  EXPECT_EQ(sim.latest(), virtual_now);
  // A replay's clock only moves with its frames: no engine deadline.
  auto replay = BusClock::replay(env);
  EXPECT_FALSE(replay.to_engine(Micros(1)));
  replay.on_frame(Micros(7));
  replay.on_frame(Micros(2'000'007));
  EXPECT_EQ(replay.now(), Micros(2'000'007));
  EXPECT_DOUBLE_EQ(replay.seconds_covered(), 2.0);
  // A real bus: the system (wall) clock.
  auto real = BusClock::system(env);
  EXPECT_EQ(real.now(), env.wall_now());
  EXPECT_EQ(real.to_engine(env.wall_now() + Micros(250'000)), env.steady_now() + 250ms);
  EXPECT_EQ(real.to_engine(env.wall_now() - Micros(1)), env.steady_now());
}

}  // namespace
}  // namespace fleetgw::runtime
