// The StateStage on its own (issue 26): the real GatewayCore and Recorder on the simulated bike
// (lockstep, virtual time) as its sources, its inputs fed by hand, run(now) on a ManualEnv, its
// outputs asserted -- no pipeline, no uplink. Checked: the state is handed over at once the
// first time, then only when it changed and never sooner than its interval after the last
// hand-over; the zones' alarm and a move beyond state_min_move_m are changes, GNSS jitter is
// not; a bike that parks puts the parked rates in the stage's output and signals its owner,
// and an unlock the riding rates.
#include <gtest/gtest.h>

#include "env/env.h"
#include "fleetgw/v1/state.pb.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/state_stage.h"
#include "runtime_test_util.h"
#include "storage/store.h"
#include "tests/geofence/zone_test_util.h"

namespace fleetgw::runtime::testing {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

// The state's bus health: up, nothing heard through it (the harness drives the core itself).
class IdleTransport final : public can::Transport {
 public:
  IdleTransport() { health_.state = can::ControllerState::kUp; }
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame&) override { return true; }
  void stop() override {}
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "idle"; }

 private:
  can::BusHealth health_;
};

struct StateRun {
  explicit StateRun(const std::filesystem::path& db)
      : h(bundled("parked"), make_config("[parked]\nsettle_s = 10\n")),
        store(storage::StoreOptions{.path = db.string()}),
        recorder(h.config, store, h.bus.now()),
        clock(BusClock::replay(env)),
        stage(StateStageConfig{.min_interval = milliseconds(5000),
                               .min_move_m = 20,
                               .parked = {.enabled = true, .settle = seconds(10)},
                               .parked_batch_delay = milliseconds(300'000)},
              StateSources{.core = h.core,
                           .trackers = recorder.trackers(),
                           .clock = clock,
                           .transport = transport},
              env, [this] { ++signals; }) {
    h.core.add_listener(recorder);
    h.core.add_listener(stage.parked_listener());
    h.start();
  }
  // Runs the stage at the engine's now; the state it handed over, if any.
  std::optional<v1::VehicleState> check() {
    stage.run(env.steady_now());
    if (!stage.state) return std::nullopt;
    v1::VehicleState s;
    EXPECT_TRUE(s.ParseFromString(*stage.state));
    stage.state.reset();
    return s;
  }

  ManualEnv env;
  SimHarness h;
  storage::Store store;
  Recorder recorder;
  IdleTransport transport;
  BusClock clock;
  StateStage stage;
  int signals = 0;
};

gnss::Fix fix_east(double east_m) {
  auto f = geofence::testing::fix_at(east_m, 0, motinova::Micros(1'000'000));
  f.satellites = 7;
  return f;
}

TEST(StateStage, HandsOverOnlyAChangedStateAndNeverSoonerThanItsInterval) {
  TempDir dir;
  StateRun run(dir.path() / "fleet.db");
  run.h.run_until(run.h.at(2));
  // The first evaluation of parked mode (riding, until the locks settle) touched the state.
  ASSERT_TRUE(run.stage.rates);
  run.stage.rates.reset();
  const auto deadline = run.stage.next_deadline();
  ASSERT_TRUE(deadline);
  EXPECT_LE(*deadline, run.env.steady_now()) << "the first at once";
  const auto first = run.check();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->active_alarms_size(), 0);
  EXPECT_FALSE(first->has_position());
  EXPECT_EQ(first->mode(), v1::VEHICLE_MODE_RIDING);
  EXPECT_EQ(run.stage.next_deadline(), std::nullopt) << "nothing touched: no wake-up for it";

  // Touched again: due only the interval after the hand-over, and then unchanged.
  run.stage.touch();
  EXPECT_EQ(run.stage.next_deadline(), run.env.steady_now() + seconds(5));
  EXPECT_FALSE(run.check()) << "not due";
  run.env.advance(seconds(5));
  EXPECT_FALSE(run.check()) << "nothing changed";

  // The zones' alarm: a change, listed after the tracker's alarms.
  run.stage.set_outside_operating_area(true);
  run.env.advance(seconds(5));
  const auto outside = run.check();
  ASSERT_TRUE(outside);
  ASSERT_EQ(outside->active_alarms_size(), 1);
  EXPECT_EQ(outside->active_alarms(0), v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);

  // A position is a change; jitter of 3 m is not; 45 m is, and carries the current fix.
  run.stage.on_position(fix_east(0));
  run.env.advance(seconds(5));
  const auto located = run.check();
  ASSERT_TRUE(located);
  EXPECT_TRUE(located->has_position());
  run.stage.on_position(fix_east(3));
  run.env.advance(seconds(5));
  EXPECT_FALSE(run.check()) << "GNSS jitter of a standing bike";
  run.stage.on_position(fix_east(45));
  run.env.advance(seconds(5));
  const auto moved = run.check();
  ASSERT_TRUE(moved);
  EXPECT_NE(moved->position().lon_e7(), located->position().lon_e7());
}

TEST(StateStage, ParkingPutsTheParkedRatesInItsOutputAndAnUnlockTheRidingRates) {
  TempDir dir;
  StateRun run(dir.path() / "fleet.db");
  run.h.run_until(run.h.at(1));
  EXPECT_EQ(run.stage.parked(), false) << "riding until the locks were still for settle_s";
  EXPECT_EQ(run.signals, 1);
  run.h.run_until(run.h.at(15));
  ASSERT_EQ(run.stage.parked(), true) << "locked and still for settle_s";
  EXPECT_EQ(run.signals, 2) << "the owner is told to settle";
  ASSERT_TRUE(run.stage.rates);
  EXPECT_TRUE(run.stage.rates->parked);
  EXPECT_EQ(run.stage.rates->telemetry_batch_delay, milliseconds(300'000));
  // The change waits in the output (counted by run) and touched the state, which says so.
  EXPECT_GE(run.stage.run(run.env.steady_now()).produced, 1u);
  ASSERT_TRUE(run.stage.state);
  v1::VehicleState s;
  ASSERT_TRUE(s.ParseFromString(*run.stage.state));
  EXPECT_EQ(s.mode(), v1::VEHICLE_MODE_PARKED);
  run.stage.rates.reset();

  // A rental unlock (the gateway opens the frame lock): riding at once, no batch delay.
  ASSERT_EQ(run.h.core.node().actuate_lock(1, node::LockTarget::kUnlocked, run.h.bus.now(),
                                           [](const node::LockResult&) {}),
            node::LockStart::kStarted);
  run.h.core.deliver_echoes();
  run.h.run_until(run.h.at(20));
  EXPECT_EQ(run.stage.parked(), false);
  EXPECT_EQ(run.signals, 3);
  ASSERT_TRUE(run.stage.rates);
  EXPECT_FALSE(run.stage.rates->parked);
  EXPECT_EQ(run.stage.rates->telemetry_batch_delay, std::nullopt);
}

}  // namespace
}  // namespace fleetgw::runtime::testing
