// The bundled alarm scenarios (config/scenarios/{theft,forced-lock,low-battery,
// battery-removed}.toml) run in lockstep through the real protocol stack and DomainTrackers:
// each raises exactly one alarm of its kind (one per threshold for low battery) with the
// evidence an operator needs, and the theft is recorded as riding-rate telemetry.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "domain_test_util.h"
#include "fleetgw/v1/alarm.pb.h"

namespace fleetgw::domain::testing {
namespace {

using storage::AlarmTransition;

std::vector<storage::AlarmRow> raised(const Collected& out, const std::string& kind) {
  std::vector<storage::AlarmRow> r;
  for (const auto& a : out.alarms) {
    if (a.record.kind == kind && a.record.transition == AlarmTransition::kRaised) {
      r.push_back(a.record);
    }
  }
  return r;
}

TEST(AlarmScenarios, TheftRaisesOneMovementAlarmAndRecordsTelemetryAtTheRidingRate) {
  Harness h(bundled("theft"));
  h.run_until_offset(140);
  const auto movement = raised(h.out, "unauthorised_movement");
  ASSERT_EQ(movement.size(), 1u);
  const storage::AlarmRow& a = movement[0];
  // The wheel starts turning at 20 s; debounced for 2 s of evidence.
  EXPECT_GE(a.first_evidence_us, h.at(20).count());
  EXPECT_LE(a.first_evidence_us, h.at(23).count());
  EXPECT_GE(a.ts_us - a.first_evidence_us, 2'000'000);
  EXPECT_LE(a.ts_us - a.first_evidence_us, 2'500'000);
  ASSERT_TRUE(a.speed_kmh);
  EXPECT_GT(*a.speed_kmh, 1.0);
  EXPECT_EQ(raised(h.out, "lock_forced").size(), 0u) << "no lock opened";
  // Telemetry while it moves locked: about one sample a second (riding rate), not one a minute.
  const auto samples = std::count_if(h.out.telemetry.begin(), h.out.telemetry.end(), [&](auto& p) {
    return p.record.ts_us >= h.at(25).count() && p.record.ts_us < h.at(75).count();
  });
  EXPECT_GE(samples, 45);
  // Cleared once, 30 s after it stopped.
  const auto cleared = std::count_if(h.out.alarms.begin(), h.out.alarms.end(), [](auto& p) {
    return p.record.transition == AlarmTransition::kCleared;
  });
  EXPECT_EQ(cleared, 1);
}

TEST(AlarmScenarios, ForcedLockRaisesOneAlarmNamingTheLock) {
  Harness h(bundled("forced-lock"));
  h.run_until_offset(90);
  const auto forced = raised(h.out, "lock_forced");
  ASSERT_EQ(forced.size(), 1u);
  EXPECT_EQ(forced[0].lock_node, 8);
  EXPECT_GE(forced[0].ts_us, h.at(20).count());
  EXPECT_LE(forced[0].ts_us, h.at(22).count());
  EXPECT_EQ(h.out.alarms.size(), 2u) << "raised at the opening, cleared at the relock";
}

TEST(AlarmScenarios, LowBatteryRaisesEachThresholdOnceInOrder) {
  Harness h(bundled("low-battery"));
  h.run_until_offset(400);
  const auto low = raised(h.out, "low_battery");
  ASSERT_EQ(low.size(), 3u);
  EXPECT_EQ(low[0].threshold_pct, 20);
  EXPECT_EQ(low[1].threshold_pct, 10);
  EXPECT_EQ(low[2].threshold_pct, 5);
  for (const auto& a : low) EXPECT_LE(*a.soc_pct, *a.threshold_pct);
}

TEST(AlarmScenarios, BatteryRemovedWhileParkedRaisesOneAlarm) {
  Harness h(bundled("battery-removed"));
  h.run_until_offset(90);
  const auto removed = raised(h.out, "battery_removed");
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_NEAR(static_cast<double>(removed[0].first_evidence_us),
              static_cast<double>(h.at(30).count()), 1'100'000);
  EXPECT_NEAR(static_cast<double>(removed[0].ts_us - removed[0].first_evidence_us), 10e6, 0.3e6);
  ASSERT_TRUE(removed[0].soc_pct);
  EXPECT_NEAR(*removed[0].soc_pct, 64, 1);
}

}  // namespace
}  // namespace fleetgw::domain::testing
