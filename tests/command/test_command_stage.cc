// The command service as a stage of the engine (issue 26, runtime/command_stage.h): the bus side
// -- CommandService::on_message/tick and the node's lock callbacks, which run inside the CAN
// transport's read handler -- never writes SQLite. A result concluded there waits in memory; the
// stage's run() writes it and its route marks the uplink in the same settle. The store is
// watched around every call into the core (Rig::inside_core): the outbox's next sequence number,
// the command's journal entry and the meta rows (speed cap, captured records) must not change
// there.
#include <asio/io_context.hpp>

#include "env/env.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/command_stage.h"
#include "gateway/runtime/engine.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

// What the store shows of the command service's writes.
struct StoreView {
  std::uint64_t next_seq = 0;
  std::string state;  // the journal entry of the watched id
  std::optional<std::string> cap;
  std::optional<std::string> captured;
  bool operator==(const StoreView&) const = default;
};

class StoreWatch {
 public:
  StoreWatch(Rig& rig, std::string id) : rig_(rig), id_(std::move(id)) {
    rig_.inside_core = [this](bool entering) {
      if (entering) {
        before_ = view();
        return;
      }
      if (!(view() == before_)) ++writes_inside;
      if (rig_.service && rig_.service->writes_pending()) ++pending_after_core;
    };
  }
  ~StoreWatch() { rig_.inside_core = nullptr; }
  StoreWatch(const StoreWatch&) = delete;
  StoreWatch& operator=(const StoreWatch&) = delete;

  StoreView view() const {
    StoreView v;
    v.next_seq = rig_.store->next_seq();
    if (const auto e = rig_.store->command(id_)) v.state = e->state;
    v.cap = rig_.store->meta("command.speed_cap_kmh");
    v.captured = rig_.store->meta("diag.captured.pack_stats");
    return v;
  }

  int writes_inside = 0;       // calls into the core during which the store changed
  int pending_after_core = 0;  // calls into the core after which a result waited for run()

 private:
  Rig& rig_;
  std::string id_;
  StoreView before_;
};

TEST(CommandStage, LockConfirmedInsideTheReadHandlerIsWrittenByTheStageNotThere) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string cmd = rig.payload("seat", "unlock", "stage-lock-1");
  StoreWatch watch(rig, "stage-lock-1");
  const auto* r = rig.run(cmd);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_TRUE(r->stored());
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kUnlocked);
  EXPECT_EQ(rig.store->command("stage-lock-1")->state, "succeeded");
  EXPECT_EQ(rig.stored_calls, 1);
  // The confirmation arrived in a frame: concluded there, written after it.
  EXPECT_GE(watch.pending_after_core, 1);
  EXPECT_EQ(watch.writes_inside, 0);
}

TEST(CommandStage, SpeedLimitAndItsCapAreWrittenTogetherByTheStage) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string cmd = rig.mc_payload("speed_limit", "15", "stage-mc-1");
  StoreWatch watch(rig, "stage-mc-1");
  const auto* r = rig.run(cmd);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_TRUE(r->stored());
  EXPECT_EQ(rig.store->meta("command.speed_cap_kmh"), "15");
  EXPECT_EQ(rig.store->command("stage-mc-1")->state, "succeeded");
  EXPECT_GE(watch.pending_after_core, 1);
  EXPECT_EQ(watch.writes_inside, 0);
}

// A kill after the bus confirmed but before the stage wrote: the journal still says
// "executing", so the next start answers it (interrupted_by_restart) without acting again.
TEST(CommandStage, AKillBeforeTheStageWroteLeavesTheJournalToRecovery) {
  Rig rig;
  rig.bus.run_for(2s);
  rig.hold_stage = true;
  const std::string cmd = rig.payload("seat", "unlock", "stage-kill-1");
  ASSERT_EQ(rig.service->on_payload(cmd, rig.bus.now()), Disposition::kStarted);
  for (int i = 0; i < 500 && !rig.service->writes_pending(); ++i) rig.bus.run_for(10ms);
  ASSERT_TRUE(rig.service->writes_pending());
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kUnlocked);
  EXPECT_EQ(rig.store->command("stage-kill-1")->state, "executing");
  EXPECT_EQ(rig.result("stage-kill-1"), nullptr);
  const Micros t0 = rig.bus.now();
  rig.restart();
  rig.hold_stage = false;
  EXPECT_EQ(rig.service->recover(rig.bus.now()), 1u);
  const auto* r = rig.result("stage-kill-1");
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_TIMEOUT);
  EXPECT_EQ(reason_code(*r), "interrupted_by_restart");
  EXPECT_EQ(rig.store->command("stage-kill-1")->state, "timeout");
  rig.bus.run_for(1s);
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
}

// A stage after the command stage, standing in for the uplink: marked by the route.
struct UplinkProbe final : runtime::Stage {
  std::string_view name() const override { return "uplink_probe"; }
  std::optional<runtime::EngineTime> next_deadline() const override { return std::nullopt; }
  runtime::StageRun run(runtime::EngineTime) override {
    if (marked) published_in_settle = settles();
    marked = false;
    return {};
  }
  std::function<std::uint64_t()> settles;
  bool marked = false;
  std::optional<std::uint64_t> published_in_settle;
};

// Through the real engine: the payload is an input of the stage, the lock's confirmation in a
// frame makes the stage due at once, and one settle writes the result and reaches the stage
// after it (the uplink publishes in the same settle as the write).
TEST(CommandStage, TheEngineWritesAResultConcludedOnTheBusAndMarksTheUplinkInOneSettle) {
  Rig rig;
  rig.bus.run_for(2s);
  rig.hold_stage = true;
  asio::io_context io;
  ManualEnv env;
  runtime::Engine engine(io, env);
  const runtime::BusClock clock = runtime::BusClock::simulated(
      env, [&rig] { return rig.bus.now(); }, 1.0);
  runtime::CommandStage stage(*rig.service, clock, nullptr, engine);
  UplinkProbe probe;
  probe.settles = [&engine] { return engine.counters().settles; };
  std::size_t stored = 0;
  engine.add(stage, [&] {
    if (stage.stored > 0) {
      stored += std::exchange(stage.stored, 0);
      probe.marked = true;
    }
    return false;
  });
  engine.add(probe);

  stage.payloads.push_back(rig.payload("seat", "unlock", "stage-engine-1"));
  EXPECT_TRUE(stage.due());
  engine.request_settle();
  io.poll();
  io.restart();
  EXPECT_EQ(stage.handled(), 1u);
  EXPECT_EQ(rig.store->command("stage-engine-1")->state, "executing");
  EXPECT_EQ(stored, 0u);

  // The lock answers on the bus; the core concludes, nothing is written there.
  for (int i = 0; i < 500 && !rig.service->writes_pending(); ++i) rig.bus.run_for(10ms);
  ASSERT_TRUE(rig.service->writes_pending());
  EXPECT_EQ(rig.store->command("stage-engine-1")->state, "executing");
  EXPECT_TRUE(stage.due());
  EXPECT_EQ(stage.next_deadline(), env.steady_now());

  // What Pipeline::on_frame does when the stage is due.
  io.restart();
  engine.request_settle();
  io.poll();
  EXPECT_FALSE(rig.service->writes_pending());
  EXPECT_EQ(rig.store->command("stage-engine-1")->state, "succeeded");
  EXPECT_EQ(stored, 1u);
  ASSERT_TRUE(probe.published_in_settle.has_value());
  EXPECT_EQ(*probe.published_in_settle, engine.counters().settles);
  const auto* r = rig.result("stage-engine-1");
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  engine.stop();
}

}  // namespace
}  // namespace fleetgw::command::testing
