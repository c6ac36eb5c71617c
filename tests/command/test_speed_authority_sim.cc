// One speed-limit authority on the bike (issue 24), against the simulated MC in lockstep: a slow
// zone and an operator's cap both go through it, and the MC is only ever given their minimum.
// The runtime's glue (Pipeline::tick_zones, pipeline_zones.cc) is mirrored by ZoneRig::tick():
// the engine's demand, the MC as the live state reports it, one write at a time through the
// command service's own-action path. The MC's limit and the bike's speed are sampled every
// 10 ms of bus time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_bundle.h"
#include "gateway/geofence/zone_controller.h"
#include "tests/command/command_test_util.h"
#include "tests/geofence/zone_test_util.h"

namespace fleetgw::command::testing {
namespace {

namespace gt = geofence::testing;

constexpr std::uint8_t kFnSettings = 0x34;
constexpr int kFactoryKmh = 25;  // the simulated MC's factory limit
constexpr int kZoneKmh = 12;

sim::Scenario riding_scenario() {
  auto sc = quiet_scenario();
  sc.locks_locked = false;
  sim::RideSegment leg;
  leg.duration_s = 3600;
  leg.speed_kmh = 25;  // the rider wants 25: the MC's limit is what holds the bike back
  sc.ride.push_back(leg);
  return sc;
}

// The command rig plus the geofence controller with one slow zone, "Old Town", 12 km/h: a
// square of 600 m around the origin. The bike is "inside" at the origin, "outside" 2 km west.
struct ZoneRig {
  Rig rig{riding_scenario()};
  std::unique_ptr<geofence::ZoneController> zones;
  bool writing = false;
  bool inside = false;
  Micros next_fix{0};
  // Samples: (bus time, MC limit in force as the simulated MC holds it, bike speed).
  struct Sample {
    Micros at;
    int mc_limit;
    double speed;
  };
  std::vector<Sample> samples;

  ZoneRig() { make_zones(); }

  void make_zones() {
    geofence::ZoneControllerConfig c;
    c.engine.margin_m = 10;
    c.engine.min_dwell = std::chrono::seconds(1);
    c.engine.speed_ramp = std::chrono::seconds(2);
    c.engine.restore_ramp = std::chrono::seconds(1);
    c.engine.unrestricted_kmh = kFactoryKmh;
    c.enforcer.own_limit_kmh = kFactoryKmh;
    // The command service's authority, as Pipeline::start_zones shares it.
    auto& speed = rig.service->speed_authority();
    speed.set_own_limit(kFactoryKmh);
    c.enforcer.speed = &speed;
    c.trusted_keys = {{kKeyId, rig.key.public_key().base64()}};
    zones = std::make_unique<geofence::ZoneController>(std::move(c));
    v1::ZoneBundle b;
    b.set_version(1);
    b.set_issued_at_us(rig.bus.now().count());
    auto* z =
        gt::add_zone(b, "old-town", v1::ZONE_KIND_SLOW, {gt::rect(-300, -300, 300, 300)}, kZoneKmh);
    z->set_name("Old Town");
    const std::string signed_bundle = geofence::sign_zone_bundle(b, rig.key, kKeyId);
    std::vector<geofence::ZoneEvent> events;
    std::string error;
    const auto v = zones->on_bundle(
        {reinterpret_cast<const std::uint8_t*>(signed_bundle.data()), signed_bundle.size()},
        rig.bus.now(), events, error);
    ASSERT_TRUE(v.accepted()) << v.detail;
  }

  int mc_limit() const { return kFactoryKmh + rig.bus.bike().state().speed_limit_offset_kmh; }

  // Pipeline::tick_zones as the runtime does it.
  void tick() {
    const Micros now = rig.bus.now();
    geofence::McView mc;
    mc.assist_level = rig.core->live().assist;
    if (const auto limit = rig.core->live().speed_limit_kmh) {
      mc.speed_limit_kmh = static_cast<int>(std::lround(*limit));
    }
    mc.busy = writing || rig.service->busy();
    const auto w = zones->tick(now, mc);
    if (!w) return;
    McRequest request;
    if (w->kind == geofence::McWrite::Kind::kSpeedLimit) {
      request.kind = McActionKind::kSpeedLimit;
      request.speed_limit_kmh = static_cast<std::uint32_t>(w->speed_limit_kmh);
    } else {
      request.kind = McActionKind::kAssistLevel;
      request.assist_level = w->assist_level;
    }
    writing = true;
    const auto refused =
        rig.service->start_own_mc_action(request, now, [this](bool ok, std::string, Micros at) {
          writing = false;
          zones->on_write_result(ok, at);
        });
    if (refused) {
      writing = false;
      zones->on_write_result(false, now);
    }
  }

  // Runs the bus for `d`: a fix every second (inside or outside), the zones ticked and the MC
  // sampled every 10 ms.
  void run_for(Micros d) {
    const Micros until = rig.bus.now() + d;
    while (rig.bus.now() < until) {
      const Micros now = rig.bus.now();
      if (now >= next_fix) {
        const auto fix = inside ? gt::fix_at(0, 0, now) : gt::fix_at(-2000, 0, now);
        std::vector<geofence::ZoneEvent> events;
        zones->on_position(now, &fix, events);
        // Pipeline::record_zone_event hands every event to the authority.
        for (const auto& e : events) rig.service->speed_authority().on_zone_event(e, e.zone_name);
        next_fix = now + std::chrono::seconds(1);
      }
      tick();
      rig.bus.run_for(10ms);
      samples.push_back({rig.bus.now(), mc_limit(), rig.bus.bike().state().speed_kmh});
    }
  }

  // A command delivered while the zones keep running; its result.
  const v1::CommandResult* command(const std::string& payload, Micros max_wait = 10s) {
    const std::string id = Rig::id_of(payload);
    const std::size_t before = rig.results.size();
    rig.service->on_payload(payload, rig.bus.now());
    const Micros until = rig.bus.now() + max_wait;
    while (rig.bus.now() < until) {
      for (std::size_t i = before; i < rig.results.size(); ++i) {
        if (rig.results[i].command_id() == id) return &rig.results[i];
      }
      run_for(10ms);
    }
    return nullptr;
  }

  // The highest MC limit sampled from `since` on.
  int max_limit_since(Micros since) const {
    int m = 0;
    for (const auto& s : samples) {
      if (s.at >= since) m = std::max(m, s.mc_limit);
    }
    return m;
  }
  double max_speed_since(Micros since) const {
    double m = 0;
    for (const auto& s : samples) {
      if (s.at >= since) m = std::max(m, s.speed);
    }
    return m;
  }
};

TEST(SpeedAuthoritySim, LeavingASlowZoneRestoresTheOperatorsLowerCapNotTheBikesOwnLimit) {
  ZoneRig z;
  z.run_for(5s);
  ASSERT_EQ(z.mc_limit(), 25);
  z.inside = true;
  z.run_for(6s);  // dwell 1 s + ramp 2 s: 12 in force
  ASSERT_EQ(z.mc_limit(), kZoneKmh);
  const Micros settled_inside = z.rig.bus.now();

  // The operator caps the bike at 20 km/h while it is inside the 12 km/h zone.
  const auto* r = z.command(z.rig.mc_payload("speed_limit", "20"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  // What is in force, and why: the zone's 12, not the operator's 20.
  EXPECT_EQ(r->mc().speed_limit_kmh(), static_cast<std::uint32_t>(kZoneKmh));
  EXPECT_EQ(r->mc().operator_cap_kmh(), 20u);
  EXPECT_EQ(r->mc().limit_in_force(), "capped at 20; 12 in force inside 'Old Town'");
  EXPECT_EQ(r->mc().writes_sent(), 0u);  // 12 was in force already
  z.run_for(3s);
  // Never above the zone's limit inside it, not even for one write.
  EXPECT_EQ(z.max_limit_since(settled_inside), kZoneKmh);

  // Out of the zone: the operator's 20 comes back, never the bike's own 25.
  z.inside = false;
  const Micros left = z.rig.bus.now();
  z.run_for(20s);
  EXPECT_EQ(z.mc_limit(), 20);
  EXPECT_LE(z.max_limit_since(left), 20);
  // The bike obeys: 10 s after the exit it rides no faster than 20 km/h (+ the sim's 0.5).
  EXPECT_LE(z.max_speed_since(left + 10s), 20.5);
}

TEST(SpeedAuthoritySim, OperatorCommandsInsideASlowZoneNeverRaiseTheLimitForAMoment) {
  ZoneRig z;
  z.inside = true;
  z.run_for(8s);
  ASSERT_EQ(z.mc_limit(), kZoneKmh);
  const Micros burst = z.rig.bus.now();
  int answered = 0;
  for (int i = 0; i < 30; ++i) {
    const auto* r = z.command(z.rig.mc_payload("speed_limit", "25"));
    ASSERT_NE(r, nullptr) << "command " << i;
    EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << i << ": " << r->reason();
    EXPECT_EQ(r->mc().speed_limit_kmh(), static_cast<std::uint32_t>(kZoneKmh)) << i;
    ++answered;
  }
  EXPECT_EQ(answered, 30);
  z.run_for(2s);
  // The MC held 12 the whole time: nothing else was written (12 was already in force).
  EXPECT_EQ(z.max_limit_since(burst), kZoneKmh);
  EXPECT_EQ(z.rig.sender.mc_writes(kFnSettings, burst), 0u);
  EXPECT_LE(z.max_speed_since(burst), kZoneKmh + 0.5);
}

TEST(SpeedAuthoritySim, TheOperatorsCapSurvivesARestartAndHoldsAfterTheNextZone) {
  ZoneRig z;
  z.run_for(2s);
  const auto* r = z.command(z.rig.mc_payload("speed_limit", "20"));
  ASSERT_NE(r, nullptr);
  ASSERT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(r->mc().limit_in_force(), "capped at 20; 20 in force");
  EXPECT_EQ(z.mc_limit(), 20);
  // A crash: service and store gone, then built again on the same file.
  z.rig.restart();
  z.samples.clear();
  z.make_zones();
  EXPECT_EQ(z.rig.service->speed_authority().operator_cap(), 20);
  z.inside = true;
  z.run_for(8s);
  EXPECT_EQ(z.mc_limit(), kZoneKmh);
  z.inside = false;
  const Micros left = z.rig.bus.now();
  z.run_for(10s);
  EXPECT_EQ(z.mc_limit(), 20);
  EXPECT_LE(z.max_limit_since(left), 20);
}

}  // namespace
}  // namespace fleetgw::command::testing
