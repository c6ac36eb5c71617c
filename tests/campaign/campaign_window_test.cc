// Window sampling around a simulated over-temperature: exactly the samples of [event - before,
// event + after], one per period per signal, from the ring and then live; and the bytes an hour
// of a cell-voltage campaign at 1 Hz (a figure of issue 29, checked against its cost bound).
#include <gtest/gtest.h>

#include <iostream>

#include "campaign_test_util.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kMs;
using test::kSecond;

TEST(CampaignWindow, CollectsExactlyTheWindowAroundAnOverTemperature) {
  auto c = test::base_campaign();
  c.clear_signals();
  c.add_signals("mc.status.motor_temp_c");
  c.add_signals("bms.cells.cells_mv[0]");
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
  auto* cond = c.mutable_trigger()->mutable_condition();
  cond->set_kind(v1::CAMPAIGN_CONDITION_KIND_ABOVE);
  cond->set_signal("mc.status.motor_temp_c");
  cond->set_threshold_e6(70'000'000);
  cond->set_hysteresis_e6(5'000'000);
  c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_WINDOW);
  c.mutable_sampling()->set_period_ms(100);
  c.mutable_sampling()->set_before_ms(2000);
  c.mutable_sampling()->set_after_ms(1000);
  CampaignEngine engine;
  engine.put(test::compiled(c), kDay0);
  test::TestBus bus(engine);
  // 20 s of bus: the motor at 60 °C, rising 2 °C per 100 ms from 10 s (72 °C, over 70, at
  // 10.6 s), falling back to 50 °C from 13 s. The MC every 100 ms, the cells 20 ms later.
  for (int k = 0; k < 200; ++k) {
    const auto t = kDay0 + k * 100 * kMs;
    double temp = 60;
    if (k >= 100 && k < 130) temp = 60 + (k - 100) * 2;
    bus.mc_temp(t, temp);
    bus.cells(t + 20 * kMs, 3300 + k);
    engine.tick(t + 20 * kMs);
  }
  std::vector<v1::CampaignSamples> records;
  const auto got = bus.samples(&records);
  std::vector<std::int64_t> mc, cells;
  for (const auto& s : got) {
    (s.signal == "mc.status.motor_temp_c" ? mc : cells).push_back((s.t - kDay0) / kMs);
  }
  std::vector<std::int64_t> want_mc, want_cells;
  for (std::int64_t t = 8600; t <= 11600; t += 100) want_mc.push_back(t);
  for (std::int64_t t = 8620; t <= 11520; t += 100) want_cells.push_back(t);
  EXPECT_EQ(mc, want_mc);
  EXPECT_EQ(cells, want_cells);
  ASSERT_FALSE(records.empty());
  for (const auto& r : records) {
    EXPECT_EQ(r.trigger_at_us(), (kDay0 + 10'600 * kMs).count());
    EXPECT_EQ(r.campaign_id(), "cells-hot");
    EXPECT_EQ(r.campaign_version(), 1u);
  }
  // The values are the bus's: cell 0 at 8.62 s was 3300 + 86 mV.
  for (const auto& s : got) {
    if (s.signal == "bms.cells.cells_mv[0]" && s.t == kDay0 + 8620 * kMs) {
      EXPECT_EQ(s.value, 3386);
    }
  }
  EXPECT_EQ(engine.view(kDay0)[0].counters.events, 1u);
}

TEST(CampaignWindow, CellVoltagesAt1HzBytesPerHour) {
  auto c = test::base_campaign();
  c.clear_signals();
  for (int i = 0; i < 16; ++i) c.add_signals("bms.cells.cells_mv[" + std::to_string(i) + "]");
  c.set_disk_budget_bytes(64 << 20);
  const auto compiled = test::compiled(c);
  CampaignEngine engine;
  engine.put(compiled, kDay0);
  test::TestBus bus(engine);
  std::uint64_t bytes = 0, records = 0, samples = 0;
  for (int k = 0; k < 36'000; ++k) {  // one hour of cells at 10 Hz
    const auto t = kDay0 + k * 100 * kMs;
    bus.cells(t, 3300 + (k % 50));
    if (k % 10 == 0) engine.tick(t);
  }
  engine.tick(kDay0 + 30 * 86'400 * kSecond);  // past its end: the rest recorded
  for (const auto& r : engine.take_records()) {
    bytes += r.payload.size();
    samples += r.samples;
    ++records;
  }
  EXPECT_EQ(samples, 16u * 3600u);
  EXPECT_LE(bytes, compiled.cost.max_bytes_per_hour);
  std::cout << "cell-voltage campaign at 1 Hz: " << bytes << " payload bytes/h in " << records
            << " records (" << samples << " samples, bound " << compiled.cost.max_bytes_per_hour
            << ")\n";
}

}  // namespace
}  // namespace fleetgw::campaign
