// The fleet-sim's traffic model (backend/fleet_sim/fleet_sim_model.h) through the ingest's decoder:
// an hour of a riding and of a parked vehicle, simulated in a loop, is accepted message by message
// (no reject), numbers its records 1..N without a hole, and has the default configuration's
// shape (a telemetry sample per second riding, per minute parked, a ride every 15 minutes).
#include <gtest/gtest.h>

#include <map>
#include <variant>

#include "backend/fleet_sim/fleet_sim_model.h"
#include "backend/ingest/envelope_rows.h"

namespace {

using fleetgw::fleet_sim::SimVehicle;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::Reject;
using fleetgw::ingest::SequenceRange;

struct HourTotals {
  std::map<std::string, int> messages_by_table;
  std::uint64_t records = 0;
  std::uint64_t bytes = 0;
  std::uint64_t last_sequence = 0;
  std::vector<std::uint64_t> sequences;
};

HourTotals simulate_hour(bool riding) {
  constexpr std::int64_t kStart = 1'800'000'000'000'000;
  SimVehicle v("sim-7", "store-7", riding, 7, kStart);
  HourTotals t;
  auto take = [&](std::vector<fleetgw::fleet_sim::SimMessage> out) {
    for (const auto& m : out) {
      auto r = fleetgw::ingest::decode_message("fleet/v1", m.topic, m.payload);
      if (const auto* rej = std::get_if<Reject>(&r)) {
        ADD_FAILURE() << m.topic << ": " << rej->code << " " << rej->detail;
        continue;
      }
      const Decoded& d = std::get<Decoded>(r);
      ++t.messages_by_table[std::string(d.rows.at(0).table->table)];
      t.records += d.records;
      EXPECT_EQ(d.records, m.records) << m.topic;
      t.bytes += m.topic.size() + m.payload.size();
      for (const SequenceRange& s : d.ranges) {
        for (std::uint64_t q = s.first; q <= s.last; ++q) t.sequences.push_back(q);
      }
    }
  };
  const std::int64_t end = kStart + 3600LL * 1'000'000;
  for (std::int64_t now = kStart; now < end; now = std::max(now + 1, v.next_due())) {
    take(v.due(now));
  }
  take(v.drain(end));
  t.last_sequence = v.last_sequence();
  return t;
}

void expect_contiguous(HourTotals& t) {
  std::sort(t.sequences.begin(), t.sequences.end());
  ASSERT_EQ(t.sequences.size(), t.last_sequence);
  for (std::size_t i = 0; i < t.sequences.size(); ++i) ASSERT_EQ(t.sequences[i], i + 1);
}

TEST(FleetSim, RidingHourIsWhatTheGatewaySends) {
  HourTotals t = simulate_hour(true);
  expect_contiguous(t);
  EXPECT_NEAR(t.messages_by_table["telemetry_samples"], 720, 10);  // 5 s batches
  EXPECT_NEAR(t.records, 3600 + 3 * 4 + 12 + 1, 20);  // samples, rides+locks, packs, info
  EXPECT_NEAR(t.messages_by_table["vehicle_state"], 720, 10);
  EXPECT_NEAR(t.messages_by_table["status"], 60, 2);
  EXPECT_GE(t.messages_by_table["rides"], 3);
  EXPECT_EQ(t.messages_by_table["device_info"], 1);
}

TEST(FleetSim, ParkedHourIsQuiet) {
  HourTotals t = simulate_hour(false);
  expect_contiguous(t);
  EXPECT_NEAR(t.messages_by_table["telemetry_samples"], 12, 2);  // 300 s batches
  EXPECT_NEAR(t.records, 60 + 12 + 1, 3);
  EXPECT_EQ(t.messages_by_table["vehicle_state"], 1);
  EXPECT_EQ(t.messages_by_table.count("rides"), 0u);
  EXPECT_LT(t.bytes, 40'000u);
}

}  // namespace
