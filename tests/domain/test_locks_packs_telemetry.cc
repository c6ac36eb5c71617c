// Lock events (every state change, intermediate states, causes), pack snapshots (period and
// lifetime-counter changes) and telemetry sampling rates (riding vs parked, discrete changes).

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "domain_test_util.h"
#include "fleetgw/v1/lock.pb.h"
#include "fleetgw/v1/pack.pb.h"
#include "fleetgw/v1/telemetry.pb.h"
#include "frames.h"

namespace fleetgw::domain::testing {
namespace {

motinova::AppFrame lock_command(motinova::Node lock, bool lock_it) {
  const int i = motinova::lock_index(lock);
  return writer(motinova::make_can_id(motinova::Node::kIot, lock),
                static_cast<uint8_t>(0x80 + 0x10 * i + (lock_it ? 2 : 3)))
      .frame();
}

TEST(Locks, EveryStateChangeWithIntermediateStatesAndCauses) {
  Harness h(bundled("ride"));
  h.run_until_offset(5);
  // The command service unlocks the frame lock (LOCK 2, node 8).
  h.gateway()->trackers().expect_lock_command(motinova::Node::kLock2, "c-42", h.bus().now());
  h.send(lock_command(motinova::Node::kLock2, false));
  h.run_until_offset(15);
  // Someone locks it again without a command we know of.
  h.send(lock_command(motinova::Node::kLock2, true));
  h.run_until_offset(30);
  // One-touch vehicle LOCK, then the battery lock (LOCK 4) is unlocked and locked again.
  h.send(lock_command(motinova::Node::kLock4, false));
  h.run_until_offset(45);
  h.send_keyword(0x760, 0x11);
  h.send(lock_command(motinova::Node::kLock4, true));
  h.run_until_offset(60);

  std::vector<storage::LockEventRow> ev;
  for (const auto& p : h.out.locks) ev.push_back(p.record);
  ASSERT_EQ(ev.size(), 8u);
  const std::vector<std::array<std::string, 4>> want = {
      {"frame", "locked", "unlocking", "command:c-42"},
      {"frame", "unlocking", "unlocked", "command:c-42"},
      {"frame", "unlocked", "locking", "local"},
      {"frame", "locking", "locked", "local"},
      {"battery", "locked", "unlocking", "local"},
      {"battery", "unlocking", "unlocked", "local"},
      {"battery", "unlocked", "locking", "vehicle_lock"},
      {"battery", "locking", "locked", "vehicle_lock"},
  };
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(ev[i].kind, want[i][0]) << i;
    EXPECT_EQ(ev[i].old_state, want[i][1]) << i;
    EXPECT_EQ(ev[i].new_state, want[i][2]) << i;
    EXPECT_EQ(ev[i].cause, want[i][3]) << i;
    EXPECT_EQ(ev[i].lock_node, i < 4 ? 8 : 0xA);
  }
  v1::LockEvent m;
  ASSERT_TRUE(m.ParseFromArray(h.out.locks[1].uplink->data(),
                               static_cast<int>(h.out.locks[1].uplink->size())));
  EXPECT_EQ(m.source(), v1::LOCK_EVENT_SOURCE_REMOTE);
  EXPECT_EQ(m.command_id(), "c-42");
  EXPECT_EQ(m.state(), v1::LOCK_STATE_UNLOCKED);
  EXPECT_EQ(m.lock_kind(), "frame");
  // Schema v1.1: every event's states are on the wire (no UNSPECIFIED between two events of one
  // lock action), with the exact names and the node named as in fault events.
  const std::map<std::string, v1::LockState> wire = {{"locked", v1::LOCK_STATE_LOCKED},
                                                     {"unlocked", v1::LOCK_STATE_UNLOCKED},
                                                     {"locking", v1::LOCK_STATE_LOCKING},
                                                     {"unlocking", v1::LOCK_STATE_UNLOCKING}};
  for (std::size_t i = 0; i < want.size(); ++i) {
    v1::LockEvent e;
    ASSERT_TRUE(e.ParseFromArray(h.out.locks[i].uplink->data(),
                                 static_cast<int>(h.out.locks[i].uplink->size())));
    EXPECT_EQ(e.previous_state(), wire.at(want[i][1])) << i;
    EXPECT_EQ(e.state(), wire.at(want[i][2])) << i;
    EXPECT_EQ(e.previous_state_name(), want[i][1]) << i;
    EXPECT_EQ(e.state_name(), want[i][2]) << i;
    EXPECT_EQ(e.node(), i < 4 ? "lock2" : "lock4") << i;
  }
}

TEST(Locks, JammedLockReportsTheFailureState) {
  Harness h(bundled("faults"));
  h.run_until_offset(20);
  ASSERT_EQ(h.out.locks.size(), 2u);
  EXPECT_EQ(h.out.locks[0].record.new_state, "unlocking");
  EXPECT_EQ(h.out.locks[1].record.old_state, "unlocking");
  EXPECT_EQ(h.out.locks[1].record.new_state, "unlock_failed");
  EXPECT_EQ(h.out.locks[1].record.kind, "seat");
  v1::LockEvent e;
  ASSERT_TRUE(e.ParseFromArray(h.out.locks[1].uplink->data(),
                               static_cast<int>(h.out.locks[1].uplink->size())));
  EXPECT_EQ(e.previous_state(), v1::LOCK_STATE_UNLOCKING);
  EXPECT_EQ(e.state(), v1::LOCK_STATE_FAULT);
  EXPECT_EQ(e.state_name(), "unlock_failed");
}

TEST(Packs, PeriodicSnapshotsWithCellStatistics) {
  Harness h(bundled("ride"));
  h.run_until_offset(12 * 60);
  const auto& packs = h.out.packs;
  ASSERT_EQ(packs.size(), 3u) << "at ~3 s, ~5 min and ~10 min";
  EXPECT_NEAR((packs[1].record.ts_us - packs[0].record.ts_us) / 1e6, 300, 0.5);
  for (const auto& p : packs) {
    const auto& s = p.record;
    ASSERT_TRUE(s.voltage_v && s.soc_pct && s.cycles && s.cell_min_mv && s.cell_max_mv);
    EXPECT_EQ(*s.cycles, 42);
    EXPECT_EQ(*s.cell_spread_mv, *s.cell_max_mv - *s.cell_min_mv);
    EXPECT_GE(*s.cell_min_index, 1);
    EXPECT_LE(*s.cell_max_index, 13) << "13S pack, unpopulated cells ignored";
    EXPECT_NE(*s.cell_min_index, *s.cell_max_index);
    EXPECT_NEAR(*s.voltage_v, *s.cell_min_mv * 13 / 1000.0, 0.5);
    EXPECT_FALSE(s.temps_c.empty());
    ASSERT_TRUE(p.uplink);
    v1::PackStatistics m;
    ASSERT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
    EXPECT_EQ(m.cells_mv_size(), 13);
    EXPECT_EQ(m.pack_serial(), "BP24050300456");
    // Schema v1.1: one current sign on the wire (discharge positive, as in telemetry); the old
    // charge-positive field is still sent for older consumers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"  // reading the deprecated field
    ASSERT_EQ(m.has_current_ma(), s.current_a.has_value());
    if (s.current_a) {
      EXPECT_TRUE(m.has_discharge_current_ma());
      EXPECT_EQ(m.discharge_current_ma(), -m.current_ma());
      EXPECT_EQ(m.discharge_current_ma(), static_cast<int>(std::lround(-*s.current_a * 1000.0)));
    }
#pragma GCC diagnostic pop
  }
}

TEST(Packs, LifetimeCounterChangeTakesASnapshotAtOnce) {
  DomainSink sink;
  DomainTrackers t(DomainConfig{}, sink);
  const Micros t0 = secs(1'700'000'000);
  auto status = [&](double s) {
    feed(t,
         writer(0x720, 0x10).value("voltage_v", 50).value("soc_pct", 80).raw("cycles", 42).frame(),
         t0 + secs(s));
  };
  auto stats = [&](double s, int over_discharge) {
    feed(t,
         writer(0x725, 0x50)
             .raw("cycles", 42)
             .raw("over_discharge_count", over_discharge)
             .raw("runtime_min", static_cast<int64_t>(s / 60))
             .frame(),
         t0 + secs(s));
  };
  status(0);
  status(4);  // the first periodic snapshot (settle 3 s)
  ASSERT_EQ(sink.batch().packs.size(), 1u);
  EXPECT_EQ(sink.batch().packs[0].record.lifetime_json, "{}");
  stats(5, 3);   // baseline
  stats(65, 3);  // runtime changed, counters did not
  status(66);
  EXPECT_EQ(sink.batch().packs.size(), 1u);
  stats(70, 4);  // over-discharge counted
  ASSERT_EQ(sink.batch().packs.size(), 2u);
  const auto j = nlohmann::json::parse(sink.batch().packs[1].record.lifetime_json);
  EXPECT_EQ(j.at("over_discharge_count"), 4);
  EXPECT_EQ(j.at("cycles"), 42);
  EXPECT_EQ(j.at("runtime_min"), 1);
  EXPECT_EQ(j.count("reserved"), 0u);
  status(71);
  feed(t, writer(0x720, 0x10).value("voltage_v", 50).raw("cycles", 43).frame(), t0 + secs(72));
  EXPECT_EQ(sink.batch().packs.size(), 3u) << "BMS cycle count changed";
}

std::size_t samples_between(const Collected& c, Micros from, Micros to) {
  std::size_t n = 0;
  for (const auto& p : c.telemetry)
    n += p.record.ts_us >= from.count() && p.record.ts_us < to.count();
  return n;
}

TEST(Telemetry, OneHertzWhileRidingWithExtraSamplesOnAssistChange) {
  Harness h(bundled("ride"));
  h.run_until_offset(800);
  // 100..600 s: riding at 1 Hz; no discrete change in that window.
  EXPECT_NEAR(static_cast<double>(samples_between(h.out, h.at(100), h.at(600))), 500, 1);
  // The switch to SPORT at 625 s adds one sample at the change.
  EXPECT_NEAR(static_cast<double>(samples_between(h.out, h.at(600), h.at(700))), 101, 1);
  const auto& p = h.out.telemetry.back();
  ASSERT_TRUE(p.uplink);
  v1::TelemetrySample m;
  ASSERT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
  EXPECT_TRUE(m.has_speed_dkmh() && m.has_voltage_mv() && m.has_soc_pct() && m.has_odo_m());
  EXPECT_NEAR(static_cast<double>(m.speed_dkmh()), *p.record.speed_kmh * 10, 0.5);
  ASSERT_TRUE(p.record.wheel_lock_state && p.record.battery_lock_state);
  EXPECT_EQ(*p.record.wheel_lock_state, 2);  // locked (the scenario rides with locks locked)
}

TEST(Telemetry, OnePerMinuteWhenParkedPlusLockChanges) {
  Harness h(bundled("parked"));
  h.run_until_offset(300);
  h.send(lock_command(motinova::Node::kLock4, false));  // battery swap: the lock opens
  h.run_until_offset(600);
  // One at the first value heard, then one per minute, plus unlocking and unlocked.
  EXPECT_NEAR(static_cast<double>(h.out.telemetry.size()), 10 + 1 + 2, 1);
  EXPECT_TRUE(h.out.rides.empty());
}

}  // namespace
}  // namespace fleetgw::domain::testing
