// Operator alarms (gateway/domain/alarm_tracker.h) from hand-built frames at chosen times:
// debounce of the movement alarm, one alarm per episode, low-battery thresholds with hysteresis,
// forced versus commanded unlock, tamper bits, and the battery going silent while parked.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "fleetgw/v1/alarm.pb.h"
#include "frames.h"
#include "gateway/domain/domain_trackers.h"

namespace fleetgw::domain::testing {
namespace {

using motinova::Micros;
using storage::AlarmTransition;

Micros at(double s) {
  return Micros(1'717'228'800'000'000) + Micros(static_cast<int64_t>(s * 1e6));
}

// Lock 2 (0x780) is the frame lock in the default U21 table.
motinova::AppFrame lock2(int state) {
  return writer(0x780, 0x10).raw("state", state).frame();
}
motinova::AppFrame lock2_faults(uint32_t bits) {
  return writer(0x780, 0x11).raw("raw", bits).frame();
}
motinova::AppFrame mc(double speed_kmh, double rpm) {
  return writer(0x710, 0x10)
      .value("speed_kmh", speed_kmh)
      .raw("motor_rpm", static_cast<int64_t>(rpm))
      .frame();
}
motinova::AppFrame bms(double soc) {
  return writer(0x720, 0x10).value("voltage_v", 48).value("soc_pct", soc).frame();
}

class Alarms : public ::testing::Test {
 protected:
  DomainSink sink;
  DomainTrackers trackers{DomainConfig{}, sink};
  std::vector<storage::PendingRow<storage::AlarmRow>> alarms;

  void feed_at(const motinova::AppFrame& f, double s) {
    feed(trackers, f, at(s));
    collect();
  }
  void tick_to(double from, double to) {
    for (auto tenth = std::llround(from * 10); tenth <= std::llround(to * 10); ++tenth) {
      trackers.tick(at(static_cast<double>(tenth) / 10));
      collect();
    }
  }
  void collect() {
    for (auto& a : sink.batch().alarms) alarms.push_back(a);
    sink.batch().clear();
  }
  std::vector<storage::AlarmRow> of_kind(const std::string& kind) const {
    std::vector<storage::AlarmRow> out;
    for (const auto& a : alarms) {
      if (a.record.kind == kind) out.push_back(a.record);
    }
    return out;
  }
  static v1::Alarm decoded(const storage::PendingRow<storage::AlarmRow>& p) {
    v1::Alarm a;
    EXPECT_TRUE(p.uplink && a.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
    return a;
  }
};

TEST_F(Alarms, AHalfSecondWheelTwitchOfALockedBikeRaisesNothing) {
  feed_at(lock2(2), 0);
  for (double s = 1.0; s <= 1.5; s += 0.1) feed_at(mc(6, 150), s);  // someone nudges it
  for (double s = 1.6; s <= 5; s += 0.1) feed_at(mc(0, 0), s);
  for (double s = 5.0; s <= 5.5; s += 0.1) feed_at(mc(6, 150), s);  // and once more
  for (double s = 5.6; s <= 40; s += 0.1) feed_at(mc(0, 0), s);
  EXPECT_TRUE(alarms.empty()) << alarms.front().record.detail;
}

TEST_F(Alarms, RidingALockedBikeRaisesExactlyOneAlarmPerEpisodeAndClears) {
  feed_at(lock2(2), 0);
  for (double s = 1.0; s <= 20; s += 0.1) feed_at(mc(14.5, 210), s);
  ASSERT_EQ(alarms.size(), 1u) << "one alarm for the whole episode, not one per sample";
  const storage::AlarmRow& raised = alarms[0].record;
  EXPECT_EQ(raised.kind, "unauthorised_movement");
  EXPECT_EQ(raised.transition, AlarmTransition::kRaised);
  EXPECT_EQ(raised.first_evidence_us, at(1.0).count());
  EXPECT_GE(raised.ts_us, at(3.0).count() - 1000) << "debounced for 2 s of evidence";
  EXPECT_LE(raised.ts_us, at(3.1).count());
  const v1::Alarm a = decoded(alarms[0]);
  EXPECT_EQ(a.kind(), v1::ALARM_KIND_UNAUTHORISED_MOVEMENT);
  EXPECT_EQ(a.transition(), v1::ALARM_TRANSITION_RAISED);
  EXPECT_EQ(a.speed_dkmh(), 145u);
  EXPECT_EQ(a.motor_rpm(), 210u);
  EXPECT_TRUE(trackers.alarms().active());

  // Stands still: cleared once, after 30 s without evidence.
  for (double s = 20.1; s <= 60; s += 0.1) feed_at(mc(0, 0), s);
  ASSERT_EQ(alarms.size(), 2u);
  EXPECT_EQ(alarms[1].record.transition, AlarmTransition::kCleared);
  EXPECT_NEAR(static_cast<double>(alarms[1].record.ts_us), static_cast<double>(at(50.0).count()),
              200'000);
  EXPECT_FALSE(trackers.alarms().active());

  // A new episode is a new alarm.
  for (double s = 61; s <= 65; s += 0.1) feed_at(mc(9, 120), s);
  EXPECT_EQ(of_kind("unauthorised_movement").size(), 3u);
}

TEST_F(Alarms, MovingWhileUnlockedOrAfterAnUnlockIsNoAlarm) {
  feed_at(lock2(1), 0);
  for (double s = 1.0; s <= 10; s += 0.1) feed_at(mc(20, 250), s);
  feed_at(writer(0x760, 0x11).frame(), 11);  // vehicle LOCK: the rental ends
  feed_at(writer(0x760, 0x12).frame(), 12);  // and a new one starts
  for (double s = 12.1; s <= 20; s += 0.1) feed_at(mc(20, 250), s);
  EXPECT_TRUE(of_kind("unauthorised_movement").empty());
}

TEST_F(Alarms, MotorTurningWhileTheVehicleIsLockedIsEvidenceToo) {
  feed_at(writer(0x760, 0x11).frame(), 0);  // vehicle LOCK, no physical lock heard
  for (double s = 1.0; s <= 4; s += 0.1) feed_at(mc(0, 90), s);
  EXPECT_EQ(of_kind("unauthorised_movement").size(), 1u);
}

TEST_F(Alarms, LockOpeningWithoutACommandIsForcedButACommandedUnlockIsNot) {
  feed_at(lock2(2), 0);
  trackers.expect_lock_command(motinova::Node::kLock2, "c-1", at(1));
  feed_at(lock2(3), 1.2);
  feed_at(lock2(1), 1.6);
  EXPECT_TRUE(alarms.empty()) << "commanded unlock";
  feed_at(lock2(2), 30);  // locked again (locally), window long over
  feed_at(lock2(3), 40);  // opens with no command
  feed_at(lock2(1), 40.5);
  const auto forced = of_kind("lock_forced");
  ASSERT_EQ(forced.size(), 1u) << "unlocking and unlocked are one episode";
  EXPECT_EQ(forced[0].transition, AlarmTransition::kRaised);
  EXPECT_EQ(forced[0].lock_node, 8);
  EXPECT_EQ(decoded(alarms[0]).lock_kind(), "frame");
  feed_at(lock2(2), 50);
  ASSERT_EQ(of_kind("lock_forced").size(), 2u);
  EXPECT_EQ(of_kind("lock_forced")[1].transition, AlarmTransition::kCleared);
}

TEST_F(Alarms, TheIotsUnlockWriteToALockIsACommandToo) {
  feed_at(lock2(2), 0);
  feed_at(writer(0x768, 0x93).frame(), 1);  // IOT -> lock 2: UNLOCK
  feed_at(lock2(3), 1.3);
  feed_at(lock2(1), 1.8);
  EXPECT_TRUE(alarms.empty());
}

TEST_F(Alarms, LockFaultBitsAreTamperRaisedOnceAndCleared) {
  for (double s = 0; s <= 2; s += 0.2) feed_at(lock2_faults(0x0040), s);
  for (double s = 2.2; s <= 3; s += 0.2) feed_at(lock2_faults(0), s);
  const auto tamper = of_kind("lock_tamper");
  ASSERT_EQ(tamper.size(), 2u);
  EXPECT_EQ(tamper[0].lock_fault_bits, 0x40);
  EXPECT_EQ(decoded(alarms[0]).lock_fault_bits(), 0x40u);
  EXPECT_EQ(tamper[1].transition, AlarmTransition::kCleared);
}

TEST_F(Alarms, LowBatteryOncePerThresholdWithHysteresis) {
  double t = 0;
  auto soc = [&](double v) { feed_at(bms(v), t += 1); };
  for (double v : {25.0, 21.0, 20.0, 19.0, 20.0, 22.0, 19.0}) soc(v);
  auto low = of_kind("low_battery");
  ASSERT_EQ(low.size(), 1u) << "20 % once, not again below 23 %";
  EXPECT_EQ(low[0].threshold_pct, 20);
  EXPECT_EQ(decoded(alarms[0]).threshold_pct(), 20u);
  EXPECT_EQ(decoded(alarms[0]).soc_pct(), 20u);
  soc(23);  // 20 + 3 % hysteresis: re-armed, cleared
  soc(20);  // crossed again
  low = of_kind("low_battery");
  ASSERT_EQ(low.size(), 3u);
  EXPECT_EQ(low[1].transition, AlarmTransition::kCleared);
  EXPECT_EQ(low[2].transition, AlarmTransition::kRaised);
  soc(4);  // 10 and 5 crossed at once: one alarm, for 5 %
  low = of_kind("low_battery");
  ASSERT_EQ(low.size(), 4u);
  EXPECT_EQ(low[3].threshold_pct, 5);
  soc(3);
  soc(7);
  EXPECT_EQ(of_kind("low_battery").size(), 4u) << "7 % is below 5 + 3 %: still armed off";
  soc(9);  // 5 % re-arms (cleared); 10 % stays crossed, never raised itself
  low = of_kind("low_battery");
  ASSERT_EQ(low.size(), 5u);
  EXPECT_EQ(low[4].transition, AlarmTransition::kCleared);
  EXPECT_EQ(low[4].threshold_pct, 5);
}

TEST_F(Alarms, BatterySilentWhileParkedIsRemovedButNotAfterAShutdown) {
  feed_at(lock2(2), 0);
  for (int i = 0; i <= 25; ++i) feed_at(bms(70), i * 0.2);
  tick_to(5.1, 14.9);
  EXPECT_TRUE(of_kind("battery_removed").empty()) << "silent for less than 10 s";
  tick_to(15.0, 30);
  auto removed = of_kind("battery_removed");
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(removed[0].first_evidence_us, at(5.0).count());
  EXPECT_EQ(removed[0].soc_pct, 70);
  feed_at(bms(70), 31);
  removed = of_kind("battery_removed");
  ASSERT_EQ(removed.size(), 2u);
  EXPECT_EQ(removed[1].transition, AlarmTransition::kCleared);

  feed_at(writer(0x760, 0x10).frame(), 32);  // IOT SHUTDOWN: silence is expected now
  tick_to(32, 60);
  EXPECT_EQ(of_kind("battery_removed").size(), 2u);
}

TEST(AlarmConfigCheck, NamesTheOffendingKey) {
  AlarmConfig c;
  c.low_battery_pct = {10, 20};
  try {
    c.validate();
    ADD_FAILURE() << "ascending thresholds accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("alarms.low_battery_pct[1]"), std::string::npos)
        << e.what();
  }
  c = AlarmConfig{};
  c.movement_debounce = std::chrono::minutes(5);
  EXPECT_THROW(c.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace fleetgw::domain::testing
