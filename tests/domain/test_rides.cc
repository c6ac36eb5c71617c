// Rides from the simulated bike: one ride per ride scenario, checked against the simulation's
// physics; parked bikes; the stationary end; a gateway restart mid-ride with a real Store.

#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include "domain_test_util.h"
#include "fleetgw/v1/ride.pb.h"

namespace fleetgw::domain::testing {
namespace {

double assist_sum(const storage::RideRow& r) {
  double s = 0;
  for (const auto& [name, t] : r.assist_time_s) s += t;
  return s;
}

// The checks every finished ride of the "ride" scenario must pass, against the bike's truth.
void expect_consistent(const Harness& h, const storage::RideRow& r) {
  const Micros start(r.start_us);
  const Micros end(*r.end_us);
  const Truth t0 = h.truth_at(start);
  const Truth t1 = h.truth_at(end);
  const double odo_km = (t1.odo_m - t0.odo_m) / 1000.0;
  EXPECT_GT(odo_km, 5.0) << "the scenario rides about 10 km";
  EXPECT_NEAR(r.distance_km, odo_km, 0.02 * odo_km) << "distance vs the MC odometer delta";
  EXPECT_NEAR(r.distance_integrated_km, odo_km, 0.02 * odo_km) << "integrated speed";
  const double wh = t1.energy_out_wh - t0.energy_out_wh;
  EXPECT_GT(wh, 10.0);
  EXPECT_NEAR(r.energy_wh, wh, 0.05 * wh) << "energy vs the simulated integral of V*I";
  EXPECT_GT(r.energy_mah, 0.0);
  ASSERT_TRUE(r.soc_start_pct && r.soc_end_pct);
  EXPECT_NEAR(*r.soc_start_pct, t0.soc_pct, 1.0);
  EXPECT_NEAR(*r.soc_end_pct, t1.soc_pct, 1.0);
  EXPECT_LT(*r.soc_end_pct, *r.soc_start_pct);
  EXPECT_NEAR(assist_sum(r), r.duration_s, 1e-3) << "assist times sum to the duration";
  EXPECT_NEAR(r.duration_s, (r.end_us.value() - r.start_us) / 1e6, 1e-6);
  EXPECT_GT(r.moving_s, 0.8 * (r.duration_s - 105 - 30)) << "two traffic lights, ~105 s";
  EXPECT_LE(r.moving_s, r.duration_s);
  EXPECT_GT(r.max_speed_kmh, 22.0);
  EXPECT_LE(r.max_speed_kmh, 26.0) << "speed limit 25 km/h + wobble";
  EXPECT_NEAR(r.avg_speed_kmh, r.distance_integrated_km / (r.moving_s / 3600.0), 1e-6);
  EXPECT_GT(r.avg_speed_kmh, 14.0);
  EXPECT_LT(r.avg_speed_kmh, 24.0);
  ASSERT_TRUE(r.start_odo_km && r.end_odo_km);
  EXPECT_NEAR(*r.start_odo_km, 1234.5, 0.2);
  EXPECT_NEAR(*r.end_odo_km - *r.start_odo_km, r.distance_km, 0.15);
}

TEST(Rides, RideScenarioEndedByVehicleLockIsOneConsistentRide) {
  Harness h(bundled("ride"));
  h.run_until_offset(1750);     // the ride profile ends at ~1680 s; the bike stands
  h.send_keyword(0x760, 0x11);  // the rental ends: one-touch LOCK
  h.run_until_offset(1760);

  const auto closed = h.out.closed_rides();
  ASSERT_EQ(closed.size(), 1u);
  const storage::RideRow& r = closed.front();
  EXPECT_FALSE(r.partial);
  EXPECT_NEAR(*r.end_us, h.at(1750).count(), 50'000) << "ends at the LOCK";
  EXPECT_LT(r.start_us, h.at(10).count()) << "starts when the bike leaves the rack";
  expect_consistent(h, r);
  EXPECT_GT(r.assist_time_s.at("norm"), 1000);
  EXPECT_NEAR(r.assist_time_s.at("sport"), 180, 1);  // the climb
  EXPECT_NEAR(r.assist_time_s.at("eco"), 90 + 0.02, 1.0);
  EXPECT_EQ(r.assist_time_s.count("unknown"), 0u);
  EXPECT_EQ(r.fault_count, 0);

  // Every record of the ride carries its id; checkpoints have no payload, the close has one.
  std::size_t checkpoints = 0;
  for (const auto& p : h.out.rides) {
    EXPECT_EQ(p.record.ride_id, r.ride_id);
    if (p.record.state == storage::RideState::kOpen) {
      ++checkpoints;
      EXPECT_FALSE(p.uplink);
    } else {
      ASSERT_TRUE(p.uplink);
      v1::RideRecord m;
      ASSERT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
      EXPECT_EQ(m.ride_id(), r.ride_id);
      EXPECT_EQ(m.started_at_us(), r.start_us);
      EXPECT_EQ(m.ended_at_us(), *r.end_us);
      EXPECT_NEAR(static_cast<double>(m.distance_odo_m()), r.distance_km * 1000, 1);
      EXPECT_NEAR(static_cast<double>(m.energy_mwh()), r.energy_wh * 1000, 1);
      EXPECT_EQ(m.soc_start_pct(), static_cast<uint32_t>(*r.soc_start_pct));
      EXPECT_FALSE(m.partial());
      uint64_t assist_ms = 0;
      for (const auto& a : m.assist_time()) {
        assist_ms += a.duration_ms();
        if (a.assist_name() == "sport") {
          EXPECT_EQ(a.assist(), 3u);
        }
      }
      EXPECT_NEAR(static_cast<double>(assist_ms), static_cast<double>(m.duration_ms()), 5);
    }
  }
  EXPECT_GE(checkpoints, 1750u / 30u) << "checkpoint every 30 s";
}

TEST(Rides, StandingStillEndsTheRideWhereItStopped) {
  DomainConfig cfg;
  cfg.ride.stationary_end = secs(120);
  Harness h(bundled("ride"), cfg);
  h.run_until_offset(1900);
  const auto closed = h.out.closed_rides();
  ASSERT_EQ(closed.size(), 1u) << "the traffic lights (45 s, 60 s) do not end the ride";
  const storage::RideRow& r = closed.front();
  // The profile ends at 1685 s (plus ~1 s braking); the ride ends there, not 120 s later.
  EXPECT_NEAR(static_cast<double>(*r.end_us - h.at(0).count()) / 1e6, 1686, 1.5);
  expect_consistent(h, r);
}

TEST(Rides, ParkedBikeProducesNoRide) {
  Harness h(bundled("parked"));
  h.run_until_offset(600);
  EXPECT_TRUE(h.out.rides.empty());
  EXPECT_FALSE(h.gateway()->trackers().rides().riding());
}

TEST(Rides, ShutdownEndsTheRide) {
  Harness h(bundled("ride"));
  h.run_until_offset(400);
  ASSERT_TRUE(h.gateway()->trackers().rides().riding());
  h.send_keyword(0x760, 0x10);  // IOT SHUTDOWN
  h.run_until_offset(410);
  const auto closed = h.out.closed_rides();
  ASSERT_EQ(closed.size(), 1u);
  EXPECT_NEAR(*closed.front().end_us, h.at(400).count(), 50'000);
  EXPECT_FALSE(h.gateway()->trackers().rides().riding());
}

TEST(Rides, LockedVehicleDoesNotStartARide) {
  Harness h(bundled("ride"));
  h.send_keyword(0x760, 0x11);  // locked before anyone rides: the MC gives no assist, and even
  h.run_until_offset(120);      // if the bike is pushed along, it is not a ride
  EXPECT_TRUE(h.out.closed_rides().empty());
  EXPECT_FALSE(h.gateway()->trackers().rides().riding());
  h.send_keyword(0x760, 0x12);  // UNLOCK: the next movement is a ride
  h.run_until_offset(200);
  EXPECT_TRUE(h.gateway()->trackers().rides().riding());
}

TEST(Rides, RestartMidRideResumesOnePartialRideCoveringTheWholeDistance) {
  TempDir dir;
  const auto db = dir.file("fleetgw.db");
  Harness h(bundled("ride"), DomainConfig{}, db);
  h.run_until_offset(700);
  ASSERT_TRUE(h.gateway()->trackers().rides().riding());
  const std::string id = h.gateway()->trackers().rides().current(h.bus().now())->ride_id;
  // The process dies mid-ride (riding at ~22 km/h); the bike rides on for 20 s unobserved.
  h.stop_gateway();
  h.run_until_offset(720);
  h.start_gateway();  // a new Store on the same file, trackers restored from open_rides()
  h.run_until_offset(1750);
  h.send_keyword(0x760, 0x11);
  h.run_until_offset(1760);
  h.stop_gateway();

  storage::Store store(storage::StoreOptions{.path = db.string()});
  EXPECT_TRUE(store.open_rides().empty());
  std::vector<nlohmann::json> rows;
  store.export_table("rides", 0, [&](const nlohmann::json& row) { rows.push_back(row); });
  ASSERT_EQ(rows.size(), 1u) << "one ride, not split";
  const auto r = store.ride(id);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->state, storage::RideState::kClosed);
  EXPECT_TRUE(r->partial);
  const double odo_km =
      (h.truth_at(Micros(*r->end_us)).odo_m - h.truth_at(Micros(r->start_us)).odo_m) / 1000.0;
  EXPECT_NEAR(r->distance_km, odo_km, 0.02 * odo_km) << "includes the 20 s nobody saw";
  // 20 s at ~22 km/h (0.12 km) were not seen by the integration.
  EXPECT_NEAR(odo_km - r->distance_integrated_km, 0.12, 0.06) << "integration missed the gap";
  EXPECT_NEAR(assist_sum(*r), r->duration_s, 1e-3);
  // The 20 s gap plus what was accumulated after the last checkpoint (at most 30 s) and lost.
  EXPECT_GE(r->assist_time_s.at("unknown"), 19.5);
  EXPECT_LE(r->assist_time_s.at("unknown"), 51);
  ASSERT_TRUE(r->soc_start_pct);
  EXPECT_NEAR(*r->soc_start_pct, 82, 1);

  // The uplink got exactly one ride record, marked partial with its reason.
  int payloads = 0;
  for (const auto& p : h.out.rides) {
    if (!p.uplink) continue;
    ++payloads;
    v1::RideRecord m;
    ASSERT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
    EXPECT_TRUE(m.partial());
    EXPECT_EQ(m.partial_reason(), "gateway_restart");
  }
  EXPECT_EQ(payloads, 1);
}

TEST(Rides, McSilentMidRideMarksThePartialFlag) {
  sim::Scenario sc = bundled("ride");
  sim::ScenarioEvent silence;
  silence.at = secs(300);
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kMc;
  silence.duration = secs(10);
  sc.events.push_back(silence);
  Harness h(std::move(sc));
  h.run_until_offset(600);
  h.send_keyword(0x760, 0x11);
  h.run_until_offset(605);
  const auto closed = h.out.closed_rides();
  ASSERT_EQ(closed.size(), 1u);
  EXPECT_TRUE(closed.front().partial);
  EXPECT_GT(closed.front().assist_time_s.at("unknown"), 7.0);
  EXPECT_NEAR(assist_sum(closed.front()), closed.front().duration_s, 1e-3);
}

}  // namespace
}  // namespace fleetgw::domain::testing
