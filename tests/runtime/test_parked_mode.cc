// Parked mode (issue 13) in lockstep on the simulator: the real GatewayCore, Recorder (domain
// trackers on a SQLite store) and ParkedController, exactly as the Pipeline wires them.
// Checked: a locked, still bike becomes parked after settle_s and its bus polling drops
// (requests counted on the bus over the same stretch with parked mode on and off); the first
// wheel movement, an unlock and an alarm each switch back to riding at once, with the normal
// poll rates.
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "gateway/runtime/parked_mode.h"
#include "gateway/runtime/recorder.h"
#include "runtime_test_util.h"
#include "storage/store.h"

namespace fleetgw::runtime::testing {
namespace {

struct ModeChange {
  Micros at;
  bool parked;
};

// SimHarness + Recorder + ParkedController, with every mode change logged.
struct ParkedRun {
  ParkedRun(sim::Scenario scenario, const std::string& extra_config,
            const std::filesystem::path& db)
      : h(std::move(scenario), make_config(extra_config)),
        store(storage::StoreOptions{.path = db.string()}),
        recorder(h.config, store, h.bus.now()),
        controller(ParkedConfig{.enabled = h.config.parked.enabled,
                                .settle = sec(h.config.parked.settle_s),
                                .poll_period = ms(h.config.parked.poll_interval_ms)},
                   recorder.trackers(), h.core, [this](bool parked) {
                     changes.push_back({h.bus.now(), parked});
                   }) {
    h.core.add_listener(recorder);
    h.core.add_listener(controller);
    h.start();
  }
  // Read requests the gateway put on the bus in [from, to) (its own broadcasts excluded:
  // 0x760 is the IOT's broadcast ID, requests go to 0x761..0x76B).
  std::size_t requests(double from, double to) const {
    std::size_t n = 0;
    for (const auto& m : h.sent) {
      if (m.frame.can_id != 0x760 && m.ts >= h.at(from) && m.ts < h.at(to)) ++n;
    }
    return n;
  }
  std::optional<ModeChange> first_change_after(double s, bool parked) const {
    for (const auto& c : changes) {
      if (c.at >= h.at(s) && c.parked == parked) return c;
    }
    return std::nullopt;
  }

  SimHarness h;
  storage::Store store;
  Recorder recorder;
  ParkedController controller;
  std::vector<ModeChange> changes;
};

constexpr const char* kQuickParking = "[parked]\nsettle_s = 10\npoll_interval_ms = 300000\n";

TEST(ParkedMode, ALockedStillBikeIsParkedAfterSettleAndPollsTheBusLess) {
  TempDir dir;
  ParkedRun on(bundled("parked"), kQuickParking, dir.path() / "on.db");
  on.h.run_until(on.h.at(600));
  ParkedRun off(bundled("parked"), "[parked]\nenabled = false\n", dir.path() / "off.db");
  off.h.run_until(off.h.at(600));

  const auto parked = on.first_change_after(0, true);
  ASSERT_TRUE(parked);
  EXPECT_GE(parked->at, on.h.at(10));
  EXPECT_LE(parked->at, on.h.at(12)) << "settle_s after the locks were first heard locked";
  EXPECT_EQ(on.controller.parked(), true);
  EXPECT_EQ(off.controller.parked(), false);

  // The same bike over the same stretch (a parked hour scaled down to 500 s): fewer requests.
  const std::size_t riding_rate = off.requests(100, 600);
  const std::size_t parked_rate = on.requests(100, 600);
  std::printf("poll requests on the bus, 100..600 s: %zu at the riding rates, %zu parked\n",
              riding_rate, parked_rate);
  ASSERT_GT(riding_rate, 0u);
  EXPECT_LT(parked_rate * 2, riding_rate) << "parked polling is at least halved";
  // Slower reads never made a node look silent: no battery_removed, no alarm at all.
  EXPECT_EQ(on.recorder.trackers().alarms().raised_total(), 0u);
}

TEST(ParkedMode, FirstWheelMovementLeavesParkedAtOnceAndRestoresPolling) {
  TempDir dir;
  // theft.toml: locked, still for 20 s, then ridden away with every lock still locked.
  ParkedRun run(bundled("theft"), kQuickParking, dir.path() / "fleet.db");
  run.h.run_until(run.h.at(40));
  ASSERT_TRUE(run.first_change_after(0, true)) << "parked before the theft";
  const auto riding = run.first_change_after(15, false);
  ASSERT_TRUE(riding);
  // The wheel starts turning at 20 s; the first MC status above walking pace ends parking.
  EXPECT_GE(riding->at, run.h.at(20));
  EXPECT_LE(riding->at, run.h.at(21.5));
  EXPECT_EQ(run.controller.parked(), false);
  // Riding rates again: the stale-rule reads (about one a second on this bike) are back.
  EXPECT_LE(run.requests(12, 20), 2u) << "parked";
  EXPECT_GE(run.requests(22, 40), 9u) << "riding";
}

TEST(ParkedMode, UnlockLeavesParkedAtOnce) {
  TempDir dir;
  ParkedRun run(bundled("parked"), kQuickParking, dir.path() / "fleet.db");
  run.h.run_until(run.h.at(60));
  ASSERT_EQ(run.controller.parked(), true);
  // The gateway opens the frame lock (lock 2), as a rental unlock does: no alarm.
  ASSERT_EQ(run.h.core.node().actuate_lock(1, node::LockTarget::kUnlocked, run.h.bus.now(),
                                           [](const node::LockResult&) {}),
            node::LockStart::kStarted);
  run.h.core.deliver_echoes();
  run.h.run_until(run.h.at(65));
  const auto riding = run.first_change_after(60, false);
  ASSERT_TRUE(riding);
  EXPECT_LE(riding->at, run.h.at(61.5)) << "the lock reports unlocked within ~1 s";
  EXPECT_FALSE(run.recorder.trackers().alarms().active()) << "a commanded unlock is no alarm";
}

TEST(ParkedMode, AnAlarmLeavesParkedAtOnce) {
  TempDir dir;
  // battery-removed.toml: parked and locked, the BMS goes silent at 30 s; the alarm follows 10 s
  // later while every lock stays locked and nothing moves.
  ParkedRun run(bundled("battery-removed"), kQuickParking, dir.path() / "fleet.db");
  run.h.run_until(run.h.at(60));
  ASSERT_TRUE(run.first_change_after(0, true));
  const auto riding = run.first_change_after(30, false);
  ASSERT_TRUE(riding) << "the battery_removed alarm ends parked mode";
  EXPECT_GE(riding->at, run.h.at(39));
  EXPECT_LE(riding->at, run.h.at(42));
  EXPECT_TRUE(run.recorder.trackers().alarms().active());
}

}  // namespace
}  // namespace fleetgw::runtime::testing
