// Each rule of the trigger and sampling language on decoded MOTINOVA messages: every test fails
// when its rule is broken (a threshold compared with >= instead of >, a hysteresis ignored, an
// edge taken from the first value, a period not kept, a window not wrapped at midnight...).
#include <gtest/gtest.h>

#include "campaign_test_util.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kMs;
using test::kSecond;

v1::Campaign condition_campaign(v1::CampaignConditionKind kind, const std::string& signal,
                                double threshold, double hysteresis = 0) {
  auto c = test::base_campaign();
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
  auto* cond = c.mutable_trigger()->mutable_condition();
  cond->set_kind(kind);
  cond->set_signal(signal);
  cond->set_threshold_e6(static_cast<std::int64_t>(threshold * 1e6));
  cond->set_hysteresis_e6(static_cast<std::uint64_t>(hysteresis * 1e6));
  return c;
}

// Feeds one motor temperature a second and returns the times (in s after kDay0) sampled.
std::vector<int> sampled_seconds(const v1::Campaign& c, const std::vector<double>& temps) {
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  for (std::size_t i = 0; i < temps.size(); ++i) {
    bus.mc_temp(kDay0 + static_cast<int>(i) * kSecond, temps[i]);
  }
  engine.tick(kDay0 + 30 * 86'400 * kSecond);  // past its end: everything recorded
  std::vector<int> out;
  for (const auto& s : bus.samples()) out.push_back(static_cast<int>((s.t - kDay0) / kSecond));
  return out;
}

TEST(CampaignTrigger, AboveStartsStrictlyOverTheThresholdAndEndsBelowTheHysteresis) {
  const auto c =
      condition_campaign(v1::CAMPAIGN_CONDITION_KIND_ABOVE, "mc.status.motor_temp_c", 60, 5);
  //                         0   1   2   3   4   5   6   7   8
  EXPECT_EQ(sampled_seconds(c, {50, 60, 61, 58, 56, 55, 54, 62, 40}),
            (std::vector<int>{2, 3, 4, 5, 7}));
}

TEST(CampaignTrigger, BelowStartsStrictlyUnderTheThresholdAndEndsOverTheHysteresis) {
  const auto c =
      condition_campaign(v1::CAMPAIGN_CONDITION_KIND_BELOW, "mc.status.motor_temp_c", 0, 3);
  //                         0   1   2   3  4  5  6
  EXPECT_EQ(sampled_seconds(c, {10, 0, -1, 2, 3, 4, -5}), (std::vector<int>{2, 3, 4, 6}));
}

// Edges and faults are instants: they are collected through a window (here 0 ms before, 0 ms
// after: exactly the value of the event's message).
v1::Campaign event_campaign(v1::CampaignConditionKind kind, const std::string& signal,
                            double threshold) {
  auto c = condition_campaign(kind, signal, threshold);
  c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_WINDOW);
  c.mutable_sampling()->set_period_ms(10);
  c.mutable_sampling()->set_after_ms(1);
  return c;
}

TEST(CampaignTrigger, RisingEdgeIsACrossingFromAtOrBelowToAbove) {
  const auto c =
      event_campaign(v1::CAMPAIGN_CONDITION_KIND_RISING_EDGE, "mc.status.motor_temp_c", 60);
  // The first value (70) has no previous one: no event. 60 -> 61 crosses; 61 -> 62 does not.
  EXPECT_EQ(sampled_seconds(c, {70, 60, 61, 62, 59, 60, 65}), (std::vector<int>{2, 6}));
}

TEST(CampaignTrigger, FallingEdgeIsACrossingFromAtOrAboveToBelow) {
  const auto c =
      event_campaign(v1::CAMPAIGN_CONDITION_KIND_FALLING_EDGE, "mc.status.motor_temp_c", 60);
  EXPECT_EQ(sampled_seconds(c, {50, 60, 59, 58, 61, 62, 40}), (std::vector<int>{2, 6}));
}

TEST(CampaignTrigger, FaultActiveIsTheBitGoingFromZeroToOne) {
  auto c = event_campaign(v1::CAMPAIGN_CONDITION_KIND_FAULT_ACTIVE,
                          "bms.faults.charge_over_heat_alarm", 0);
  c.clear_signals();
  c.add_signals("bms.faults.raw");
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  const std::int64_t alarm = 0x00100000;  // charge_over_heat_alarm in the normalised word
  const std::int64_t other = 0x00000004;  // short_circuit_protect
  const std::vector<std::int64_t> words{alarm, 0, other, other | alarm, alarm, 0, alarm};
  for (std::size_t i = 0; i < words.size(); ++i) {
    bus.bms_faults(kDay0 + static_cast<int>(i) * kSecond, words[i]);
  }
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  std::vector<int> at;
  for (const auto& s : bus.samples()) at.push_back(static_cast<int>((s.t - kDay0) / kSecond));
  // Not at 0 (no previous value), at 3 (other bit already set) and 6.
  EXPECT_EQ(at, (std::vector<int>{3, 6}));
}

TEST(CampaignTrigger, AlwaysKeepsOneSamplePerPeriodOnTheBusTimeline) {
  auto c = test::base_campaign();
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  // A value every 300 ms for 3 s: the first of each period of 1 s after the previous sample.
  for (int i = 0; i <= 10; ++i) bus.mc_temp(kDay0 + i * 300 * kMs, 40 + i);
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  std::vector<std::int64_t> ms;
  for (const auto& s : bus.samples()) ms.push_back((s.t - kDay0) / kMs);
  EXPECT_EQ(ms, (std::vector<std::int64_t>{0, 1200, 2400}));
}

TEST(CampaignTrigger, OnChangeSamplesOnlyChangedValues) {
  auto c = test::base_campaign();
  c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_ON_CHANGE);
  EXPECT_EQ(sampled_seconds(c, {40, 40, 41, 41, 41, 40, 40}), (std::vector<int>{0, 2, 5}));
}

TEST(CampaignTrigger, TimeWindowFollowsTheBikesClockAndWrapsAtMidnight) {
  auto c = test::base_campaign();
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_TIME_WINDOW);
  c.mutable_trigger()->set_day_start_s(86'400 - 2);  // 23:59:58 .. 00:00:02
  c.mutable_trigger()->set_day_end_s(2);
  c.set_start_us((kDay0 - 86'400 * kSecond).count());
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  for (int i = -4; i <= 4; ++i) bus.mc_temp(kDay0 + i * kSecond, 40);
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  std::vector<int> at;
  for (const auto& s : bus.samples()) at.push_back(static_cast<int>((s.t - kDay0) / kSecond));
  EXPECT_EQ(at, (std::vector<int>{-2, -1, 0, 1}));
}

TEST(CampaignTrigger, NothingBeforeStartOrFromEnd) {
  auto c = test::base_campaign();
  c.set_start_us((kDay0 + 2 * kSecond).count());
  c.set_end_us((kDay0 + 5 * kSecond).count());
  EXPECT_EQ(sampled_seconds(c, {1, 2, 3, 4, 5, 6, 7}), (std::vector<int>{2, 3, 4}));
}

TEST(CampaignTrigger, ACampaignForOtherFirmwareIsIgnoredAndOneForThisFirmwareRuns) {
  auto c = test::base_campaign();
  auto* fw = c.mutable_target()->add_firmware();
  fw->set_node("bms");
  fw->add_versions("BMS-2.1.0");
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  bus.mc_temp(kDay0, 40);  // the BMS has not said its firmware yet: waiting
  EXPECT_EQ(engine.view(kDay0)[0].state, RunState::kWaitingFirmware);
  bus.bms_firmware(kDay0 + kSecond, "BMS-1.9.9");
  bus.mc_temp(kDay0 + 2 * kSecond, 41);
  EXPECT_EQ(engine.view(kDay0)[0].state, RunState::kNotTargeted);
  bus.bms_firmware(kDay0 + 3 * kSecond, "BMS-2.1.0");  // updated on the bike
  bus.mc_temp(kDay0 + 4 * kSecond, 42);
  EXPECT_EQ(engine.view(kDay0)[0].state, RunState::kRunning);
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  const auto got = bus.samples();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].value, 42);
}

TEST(CampaignTrigger, TheDiskBudgetDropsSamplesUntilRecordsLeaveTheStore) {
  auto c = test::base_campaign();
  c.set_disk_budget_bytes(4096);
  c.mutable_sampling()->set_period_ms(10);
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  for (int i = 0; i < 400; ++i) bus.mc_temp(kDay0 + i * 10 * kMs, 40);
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  const auto v = engine.view(kDay0)[0];
  const std::uint64_t per_sample =
      sample_bytes_bound(*motinova::SignalCatalogue::standard().find("mc.status.motor_temp_c"));
  EXPECT_EQ(v.counters.samples, 4096 / per_sample);
  EXPECT_EQ(v.counters.samples + v.counters.dropped, 400u);
  EXPECT_LE(v.counters.bytes_in_store, 4096u);
}

TEST(CampaignTrigger, TimeWindowWithinADayIsHalfOpen) {
  auto c = test::base_campaign();
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_TIME_WINDOW);
  c.mutable_trigger()->set_day_start_s(2);  // 00:00:02 .. 00:00:05
  c.mutable_trigger()->set_day_end_s(5);
  EXPECT_EQ(sampled_seconds(c, {40, 40, 40, 40, 40, 40, 40}), (std::vector<int>{2, 3, 4}));
}

TEST(CampaignTrigger, InvalidValuesNeverTripACondition) {
  // 0xFF in the MC's state of charge is the protocol's "not available": not 255 %.
  const auto c = condition_campaign(v1::CAMPAIGN_CONDITION_KIND_ABOVE, "mc.status.soc_pct", 60);
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  bus.mc_status_raw(kDay0, "soc_pct", 50);
  bus.mc_status_raw(kDay0 + kSecond, "soc_pct", 0xFF);
  bus.mc_status_raw(kDay0 + 2 * kSecond, "soc_pct", 55);
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  EXPECT_TRUE(bus.samples().empty());
  EXPECT_EQ(engine.view(kDay0)[0].counters.events, 0u);
}

// Zone triggers (issue 29): while the geofence says the bike is inside the named zone (its id
// or its name), from the enter event to the exit event, and from the start when a campaign
// arrives while the bike is already inside.
TEST(CampaignTrigger, ZoneHoldsWhileTheBikeIsInsideTheNamedZone) {
  auto c = test::base_campaign();
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_ZONE);
  c.mutable_trigger()->set_zone("depot");
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  for (int i = 0; i < 8; ++i) {
    if (i == 2) engine.on_zone("z-1", "depot", true);
    if (i == 3) engine.on_zone("z-2", "market", true);  // another zone changes nothing
    if (i == 5) engine.on_zone("z-2", "market", false);
    if (i == 6) engine.on_zone("z-1", "depot", false);
    bus.mc_temp(kDay0 + i * kSecond, 40);
  }
  engine.tick(kDay0 + 30 * 86'400 * kSecond);
  std::vector<int> at;
  for (const auto& s : bus.samples()) at.push_back(static_cast<int>((s.t - kDay0) / kSecond));
  EXPECT_EQ(at, (std::vector<int>{2, 3, 4, 5}));

  // By id, and a campaign put while the bike is already inside collects at once.
  c.mutable_trigger()->set_zone("z-9");
  CampaignEngine later;
  later.on_zone("z-9", "yard", true);
  later.put(test::compiled(c), kDay0);
  test::TestBus bus2(later);
  bus2.mc_temp(kDay0, 40);
  later.on_zone("z-9", "yard", false);
  bus2.mc_temp(kDay0 + kSecond, 40);
  later.tick(kDay0 + 30 * 86'400 * kSecond);
  EXPECT_EQ(bus2.samples().size(), 1u);
}

TEST(CampaignTrigger, AZoneTriggerNeedsAZoneName) {
  auto c = test::base_campaign();
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_ZONE);
  auto r = compile_campaign(c);
  ASSERT_TRUE(std::holds_alternative<std::string>(r));
  EXPECT_EQ(std::get<std::string>(r).rfind("trigger.zone:", 0), 0u) << std::get<std::string>(r);
  c.mutable_trigger()->set_zone(std::string(65, 'z'));
  EXPECT_TRUE(std::holds_alternative<std::string>(compile_campaign(c)));
  c.mutable_trigger()->set_zone("depot\n");
  EXPECT_TRUE(std::holds_alternative<std::string>(compile_campaign(c)));
  c.mutable_trigger()->set_zone("depot north");
  EXPECT_TRUE(std::holds_alternative<CompiledCampaign>(compile_campaign(c)));
}

}  // namespace
}  // namespace fleetgw::campaign
