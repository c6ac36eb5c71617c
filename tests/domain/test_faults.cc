// Fault events: raise/clear pairs from the simulator's fault scenario, debouncing of a flapping
// bit, and "unknown" (word silent) as a kind distinct from "cleared".

#include <gtest/gtest.h>

#include "domain_test_util.h"
#include "fleetgw/v1/fault.pb.h"
#include "frames.h"

namespace fleetgw::domain::testing {
namespace {

using storage::FaultEventKind;

std::vector<storage::FaultEventRow> events_of(const Collected& c, int node, std::string_view name) {
  std::vector<storage::FaultEventRow> out;
  for (const auto& p : c.faults) {
    if (p.record.node == node && p.record.name == name) out.push_back(p.record);
  }
  return out;
}

double offset_s(const Harness& h, int64_t us) {
  return (us - h.at(0).count()) / 1e6;
}

TEST(Faults, FaultScenarioGivesRaiseClearPairsWithCatalogueNames) {
  Harness h(bundled("faults"));
  h.run_until_offset(900);

  const auto heat = events_of(h.out, 1, "over_heat_protect");
  ASSERT_EQ(heat.size(), 2u);
  EXPECT_EQ(heat[0].event, FaultEventKind::kRaised);
  EXPECT_NEAR(offset_s(h, heat[0].first_seen_us), 240, 0.5);
  EXPECT_EQ(heat[0].code, 14);
  EXPECT_EQ(heat[0].severity, "critical");
  EXPECT_EQ(heat[0].bit, 4);
  EXPECT_EQ(heat[1].event, FaultEventKind::kCleared);
  EXPECT_EQ(heat[1].first_seen_us, heat[0].first_seen_us);
  EXPECT_NEAR(offset_s(h, heat[1].last_seen_us), 330, 0.5);
  EXPECT_EQ(heat[1].occurrences, 1);

  const auto alarm = events_of(h.out, 2, "discharge_over_heat_alarm");
  ASSERT_EQ(alarm.size(), 2u);
  EXPECT_EQ(alarm[0].event, FaultEventKind::kRaised);
  EXPECT_NEAR(offset_s(h, alarm[0].first_seen_us), 500, 0.5);
  EXPECT_EQ(alarm[1].event, FaultEventKind::kCleared);
  EXPECT_NEAR(offset_s(h, alarm[1].last_seen_us), 620, 0.5);
  EXPECT_EQ(alarm[0].severity, "warning");

  // Lock 4 (node 0xA) under-voltage for a minute.
  std::vector<storage::FaultEventRow> lock4;
  for (const auto& p : h.out.faults) {
    if (p.record.node == 0xA) lock4.push_back(p.record);
  }
  ASSERT_EQ(lock4.size(), 2u);
  EXPECT_EQ(lock4[0].bit, 1);
  EXPECT_EQ(lock4[0].event, FaultEventKind::kRaised);
  EXPECT_EQ(lock4[1].event, FaultEventKind::kCleared);

  // The jammed seat lock (node 7) raises its stall bit and keeps it; the silent lock 3 says
  // nothing at all (never heard is not a fault event).
  bool stall = false;
  for (const auto& p : h.out.faults) {
    EXPECT_NE(p.record.node, 9);
    if (p.record.node == 7 && p.record.bit == 6) {
      EXPECT_EQ(p.record.event, FaultEventKind::kRaised);
      stall = true;
    }
  }
  EXPECT_TRUE(stall);

  // Every cleared event closes an earlier raise of the same bit; every event has its payload.
  for (std::size_t i = 0; i < h.out.faults.size(); ++i) {
    const auto& e = h.out.faults[i].record;
    ASSERT_TRUE(h.out.faults[i].uplink);
    v1::FaultEvent m;
    ASSERT_TRUE(m.ParseFromArray(h.out.faults[i].uplink->data(),
                                 static_cast<int>(h.out.faults[i].uplink->size())));
    EXPECT_EQ(m.name(), e.name);
    EXPECT_EQ(m.bit(), static_cast<uint32_t>(e.bit));
    if (e.event != FaultEventKind::kCleared) continue;
    EXPECT_EQ(m.kind(), v1::FAULT_EVENT_KIND_CLEARED);
    bool raised = false;
    for (std::size_t j = 0; j < i; ++j) {
      const auto& r = h.out.faults[j].record;
      raised |= r.node == e.node && r.bit == e.bit && r.event == FaultEventKind::kRaised &&
                r.first_seen_us == e.first_seen_us;
    }
    EXPECT_TRUE(raised) << e.name;
  }

  // Faults raised while riding count for the ride (which is still open at 900 s).
  const auto ride = h.gateway()->trackers().rides().current(h.bus().now());
  ASSERT_TRUE(ride);
  EXPECT_GE(ride->fault_count, 3);
}

class FaultUnits : public ::testing::Test {
 protected:
  DomainSink sink;
  DomainTrackers t{DomainConfig{}, sink};
  Micros t0 = secs(1'700'000'000);
  Micros at(double s) const { return t0 + secs(s); }
  std::vector<storage::FaultEventRow> events() {
    std::vector<storage::FaultEventRow> out;
    for (const auto& p : sink.batch().faults) out.push_back(p.record);
    return out;
  }
  // The MC repeats its word every 200 ms; `word_at(s)` says what it is at offset s.
  template <typename Fn>
  void stream(double from, double to, Fn word_at) {
    for (double s = from; s < to - 1e-9; s += 0.2) feed(t, mc_faults(word_at(s)), at(s));
  }
};

TEST_F(FaultUnits, FlappingBitWithinDebounceIsOneEpisodeWithOccurrences) {
  // Bit 0x10 set 0-1 s, clear 1-2 s, set 2-3 s, clear from 3 s (debounce 3 s).
  stream(0, 12, [](double s) { return (s < 1 || (s >= 2 && s < 3)) ? 0x10u : 0u; });
  auto ev = events();
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].event, FaultEventKind::kRaised);
  EXPECT_EQ(ev[0].occurrences, 1);
  EXPECT_EQ(ev[1].event, FaultEventKind::kCleared);
  EXPECT_EQ(ev[1].occurrences, 2);
  EXPECT_EQ(ev[1].first_seen_us, at(0).count());
  EXPECT_NEAR(static_cast<double>(ev[1].last_seen_us), static_cast<double>(at(2.8).count()), 1);

  // Raised again well after the window: a new pair.
  stream(12, 20, [](double s) { return s < 13 ? 0x10u : 0u; });
  ev = events();
  ASSERT_EQ(ev.size(), 4u);
  EXPECT_EQ(ev[2].event, FaultEventKind::kRaised);
  EXPECT_EQ(ev[2].first_seen_us, at(12).count());
  EXPECT_EQ(ev[3].event, FaultEventKind::kCleared);
  EXPECT_EQ(ev[3].occurrences, 1);
}

TEST_F(FaultUnits, ClearNotReportedBeforeTheDebounceWindowEnds) {
  stream(0, 3.9, [](double s) { return s < 1 ? 0x10u : 0u; });
  EXPECT_EQ(events().size(), 1u) << "cleared at 1 s, window ends at 4 s";
  stream(3.9, 4.5, [](double) { return 0u; });
  EXPECT_EQ(events().size(), 2u);
}

TEST_F(FaultUnits, SilentWordIsUnknownThenStillActiveIsNotReraised) {
  stream(0, 1, [](double) { return 0x10u; });
  t.tick(at(2.5));
  EXPECT_EQ(events().size(), 1u) << "1.7 s of silence: not yet stale";
  t.tick(at(3.5));
  auto ev = events();
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[1].event, FaultEventKind::kUnknown);
  EXPECT_EQ(ev[1].name, "over_heat_protect");
  // Heard again, still set: no new raise, the episode continues.
  stream(10, 12, [](double) { return 0x10u; });
  EXPECT_EQ(events().size(), 2u);
  EXPECT_EQ(t.faults().active(motinova::Node::kMc), 1u);
  // Then it clears: one cleared event for the original episode.
  stream(12, 16, [](double) { return 0u; });
  ev = events();
  ASSERT_EQ(ev.size(), 3u);
  EXPECT_EQ(ev[2].event, FaultEventKind::kCleared);
  EXPECT_EQ(ev[2].first_seen_us, at(0).count());
  EXPECT_EQ(ev[2].occurrences, 1);
}

TEST_F(FaultUnits, SilentWordThatReturnsClearIsClearedNotRaised) {
  stream(0, 1, [](double) { return 0x10u | 0x20u; });
  t.tick(at(4));
  ASSERT_EQ(events().size(), 4u);  // two raised, two unknown
  // Back with only 0x20 set: 0x10 is cleared (after the window), 0x20 is not raised again.
  stream(20, 25, [](double) { return 0x20u; });
  const auto ev = events();
  ASSERT_EQ(ev.size(), 5u);
  EXPECT_EQ(ev[4].event, FaultEventKind::kCleared);
  EXPECT_EQ(ev[4].bit, 4);
}

TEST_F(FaultUnits, UndefinedBitIsReportedNotDropped) {
  feed(t, mc_faults(0x80000000u), at(0));
  const auto ev = events();
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].bit, 31);
  EXPECT_FALSE(ev[0].name.empty());
  EXPECT_FALSE(ev[0].severity.empty());
}

}  // namespace
}  // namespace fleetgw::domain::testing
