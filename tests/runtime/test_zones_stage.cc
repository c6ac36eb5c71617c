// The ZonesStage on its own (issue 26): typed inputs in, run(now) on a ManualEnv, typed
// outputs asserted -- no pipeline, no bus, no broker, no gpsd. Checked: a bundle is judged,
// stored and put in force, and a forged one changes nothing but the refusal the status shows;
// positions raise the outside_operating_area alarm only after the dwell and clear it with its
// first evidence kept; a slow zone asks for one MC write at a time, none while the command
// service is busy, and a refused start is retried only after the enforcer's retry interval; a
// lock on the bike inside a no-parking zone is reported once per parking, a lock command
// refused there, and an unknown position never refuses; the deadline is the zones' next change
// in engine time from the same Env.
#include <gtest/gtest.h>

#include <filesystem>

#include "env/env.h"
#include "fleetgw/v1/zones.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/geofence/zone_bundle.h"
#include "gateway/runtime/zones_stage.h"
#include "tests/geofence/zone_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::runtime {
namespace {

using geofence::testing::add_zone;
using geofence::testing::fix_at;
using geofence::testing::rect;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr const char* kFleetTopic = "fleet/zones";

class ZonesStageTest : public ::testing::Test {
 protected:
  fleetgw::testing::TempDir dir{"zones-stage"};
  ManualEnv env;
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();

  ZonesStageConfig config(bool refuse_locks = false) {
    ZonesStageConfig c;
    c.controller.engine.min_dwell = seconds(2);
    c.controller.engine.speed_ramp = seconds(4);
    c.controller.engine.refuse_ride_ending_locks = refuse_locks;
    c.controller.trusted_keys = {{"ops", key.public_key().base64()}};
    c.controller.bundle_file = dir / "zones.pb";
    c.controller.vehicle_id = "bike-1";
    c.topics = {kFleetTopic, "fleet/bike-1/zones"};
    c.max_bundle_bytes = 1 << 20;
    return c;
  }
  uplink::ZoneBundleMessage bundle(v1::ZoneKind kind, std::uint32_t kmh = 0) {
    v1::ZoneBundle b;
    b.set_version(7);
    b.set_issued_at_us((env.wall_now() - seconds(60)).count());
    add_zone(b, "z1", kind, {rect(-300, -300, 300, 300)}, kmh);
    return {kFleetTopic, geofence::sign_zone_bundle(b, key, "ops"), 0};
  }
  // A position received now, `east_m` east of the zone's centre.
  void position(ZonesStage& stage, double east_m) {
    stage.on_position(env.wall_now(), fix_at(east_m, 0, env.wall_now()));
  }
  // Runs the stage every 100 ms of both clocks for `d`; the MC writes it asked for.
  std::vector<ZonesStage::McWriteRequest> run_for(ZonesStage& stage, milliseconds d) {
    std::vector<ZonesStage::McWriteRequest> writes;
    for (auto t = milliseconds(0); t < d; t += milliseconds(100)) {
      env.advance(milliseconds(100));
      stage.run(env.steady_now());
      if (stage.mc_write) {
        asked_at_ = env.wall_now();
        writes.push_back(std::move(*stage.mc_write));
        stage.mc_write.reset();
      }
    }
    return writes;
  }
  Micros asked_at_{0};  // when run_for() last saw a write asked for
};

TEST_F(ZonesStageTest, ABundleIsJudgedStoredAndEnforcedAndAForgedOneOnlyRefused) {
  ZonesStage stage(config(), env);
  stage.restore();
  EXPECT_FALSE(stage.controller().authority().in_force()) << "no stored bundle yet";

  stage.on_bundle(bundle(v1::ZONE_KIND_OPERATING_AREA));
  EXPECT_EQ(stage.next_deadline(), env.steady_now()) << "an input waits: due at once";
  stage.run(env.steady_now());
  ASSERT_TRUE(stage.controller().authority().in_force());
  EXPECT_EQ(stage.controller().authority().in_force()->zones->version, 7u);
  EXPECT_TRUE(std::filesystem::exists(dir / "zones.pb")) << "stored before it is enforced";
  EXPECT_TRUE(stage.take_state_touched());
  EXPECT_TRUE(stage.alarms.empty()) << "no position yet: the area is not judged";

  // Signed by a key nobody trusts: refused, version 7 stays, the topic kept for the status.
  const auto stranger = command::Ed25519PrivateKey::generate();
  v1::ZoneBundle forged;
  forged.set_version(8);
  forged.set_issued_at_us(env.wall_now().count());
  stage.on_bundle({"fleet/bike-1/zones", geofence::sign_zone_bundle(forged, stranger, "ops"), 0});
  stage.run(env.steady_now());
  EXPECT_EQ(stage.controller().authority().in_force()->zones->version, 7u);
  EXPECT_EQ(stage.last_refusal_topic(), "fleet/bike-1/zones");
  EXPECT_EQ(stage.controller().counters().refused, 1u);
}

TEST_F(ZonesStageTest, PositionsRaiseTheAreaAlarmAfterTheDwellAndClearItWithItsFirstEvidence) {
  ZonesStage stage(config(), env);
  stage.on_bundle(bundle(v1::ZONE_KIND_OPERATING_AREA));
  stage.run(env.steady_now());
  (void)stage.take_state_touched();
  // Inside, confirmed after the dwell: an enter event, no alarm.
  position(stage, 0);
  stage.run(env.steady_now());
  env.advance(seconds(2));
  position(stage, 0);
  const StageRun entered = stage.run(env.steady_now());
  ASSERT_EQ(stage.records.size(), 1u);
  EXPECT_EQ(stage.records[0].row.kind, "operating_area");
  EXPECT_EQ(stage.records[0].row.transition, "enter");
  EXPECT_FALSE(stage.records[0].payload.empty());
  EXPECT_EQ(entered.produced, 1u);
  stage.records.clear();

  // Out of the area: nothing before the dwell, then the exit and the raised alarm.
  env.advance(seconds(1));
  position(stage, 800);
  stage.run(env.steady_now());
  EXPECT_TRUE(stage.alarms.empty()) << "one fix outside is not yet outside";
  env.advance(seconds(2));
  const Micros raised_at = env.wall_now();
  position(stage, 800);
  stage.run(env.steady_now());
  ASSERT_EQ(stage.alarms.size(), 1u);
  EXPECT_EQ(stage.alarms[0].row.kind, "outside_operating_area");
  EXPECT_EQ(stage.alarms[0].row.transition, storage::AlarmTransition::kRaised);
  EXPECT_EQ(stage.alarms[0].row.ts_us, raised_at.count());
  EXPECT_TRUE(stage.outside_operating_area());
  EXPECT_TRUE(stage.take_state_touched()) << "the retained state lists the alarm";
  stage.alarms.clear();
  stage.records.clear();

  // Back inside: cleared, naming when it was first raised.
  env.advance(seconds(30));
  position(stage, 0);
  stage.run(env.steady_now());
  env.advance(seconds(2));
  position(stage, 0);
  stage.run(env.steady_now());
  ASSERT_EQ(stage.alarms.size(), 1u);
  EXPECT_EQ(stage.alarms[0].row.transition, storage::AlarmTransition::kCleared);
  EXPECT_EQ(stage.alarms[0].row.ts_us, env.wall_now().count());
  EXPECT_EQ(stage.alarms[0].row.first_evidence_us, raised_at.count());
  EXPECT_FALSE(stage.outside_operating_area());
}

TEST_F(ZonesStageTest, ASlowZoneAsksForOneMcWriteAtATimeAndRetriesARefusedStartLater) {
  ZonesStage stage(config(), env);
  stage.set_mc({.speed_limit_kmh = 25, .assist_level = "norm", .busy = false});
  stage.on_bundle(bundle(v1::ZONE_KIND_SLOW, 12));
  stage.run(env.steady_now());
  position(stage, 0);
  stage.run(env.steady_now());
  env.advance(seconds(2));
  position(stage, 0);
  stage.run(env.steady_now());
  ASSERT_EQ(stage.records.size(), 1u);
  EXPECT_EQ(stage.records[0].row.speed_limit_kmh, 12);
  // The ramp has steps to come: the deadline is the next one, on the engine's clock.
  const auto deadline = stage.next_deadline();
  ASSERT_TRUE(deadline);
  EXPECT_GT(*deadline, env.steady_now());
  EXPECT_LE(*deadline, env.steady_now() + seconds(4));

  // The first write of the ramp; none other while it runs, however far the ramp goes.
  auto writes = run_for(stage, seconds(1));
  ASSERT_EQ(writes.size(), 1u);
  const Micros first_asked = asked_at_;
  EXPECT_EQ(writes[0].request.kind, command::McActionKind::kSpeedLimit);
  EXPECT_LT(writes[0].request.speed_limit_kmh, 25u);
  EXPECT_NE(writes[0].what.find("speed limit"), std::string::npos);
  EXPECT_TRUE(stage.write_running());
  EXPECT_TRUE(run_for(stage, seconds(2)).empty()) << "one write at a time";

  // Refused at its start: asked again only the enforcer's retry interval (5 s) after.
  stage.on_write_refused("mc_offline: no answer from the MC");
  EXPECT_FALSE(stage.write_running());
  EXPECT_TRUE(run_for(stage, std::chrono::duration_cast<milliseconds>(
                                 first_asked + milliseconds(4800) - env.wall_now()))
                  .empty());
  writes = run_for(stage, milliseconds(400));
  ASSERT_EQ(writes.size(), 1u) << "retried after 5 s";

  // Refused again, and the command service then busy: never while it is.
  stage.on_write_refused("mc_busy: a remote MC command runs");
  stage.set_mc({.speed_limit_kmh = 25, .assist_level = "norm", .busy = true});
  EXPECT_TRUE(run_for(stage, seconds(6)).empty()) << "never while the command service is busy";
  stage.set_mc({.speed_limit_kmh = 25, .assist_level = "norm", .busy = false});
  writes = run_for(stage, milliseconds(300));
  ASSERT_EQ(writes.size(), 1u) << "asked for once the service is free";
  EXPECT_EQ(writes[0].request.speed_limit_kmh, 12u) << "the latest value, steps skipped";
  // Confirmed: the MC now shows 12 and nothing more is written.
  stage.on_write_done(true, "");
  stage.set_mc({.speed_limit_kmh = 12, .assist_level = "norm", .busy = false});
  EXPECT_TRUE(run_for(stage, seconds(5)).empty());
}

TEST_F(ZonesStageTest, ALockInANoParkingZoneIsReportedOncePerParkingAndALockCommandRefused) {
  ZonesStage stage(config(/*refuse_locks=*/true), env);
  stage.on_bundle(bundle(v1::ZONE_KIND_NO_PARKING));
  stage.run(env.steady_now());
  // No position known: a rider must always be able to end a ride.
  EXPECT_EQ(stage.judge_lock(true), std::nullopt);
  EXPECT_TRUE(stage.records.empty());

  position(stage, 0);
  stage.run(env.steady_now());
  const auto refusal = stage.judge_lock(true);
  ASSERT_TRUE(refusal);
  EXPECT_NE(refusal->find("no-parking zone 'z1'"), std::string::npos) << *refusal;
  ASSERT_EQ(stage.records.size(), 1u);
  EXPECT_EQ(stage.records[0].row.transition, "lock_refused");
  stage.records.clear();

  // Locked on the bike (not by a command): reported at the next run, at the fix of the lock.
  stage.on_lock_event("frame", 2, "vehicle_lock");
  stage.on_lock_event("wheel", 2, "vehicle_lock");  // the same parking: judged once
  stage.on_lock_event("frame", 2, "command:abc");   // a command's lock: judged by the guard
  EXPECT_EQ(stage.next_deadline(), env.steady_now());
  const StageRun r = stage.run(env.steady_now());
  ASSERT_EQ(stage.records.size(), 1u);
  EXPECT_EQ(stage.records[0].row.transition, "locked_in_no_parking");
  EXPECT_EQ(stage.records[0].event.kind, geofence::ZoneKind::kNoParking);
  EXPECT_EQ(r.produced, 1u);
  stage.records.clear();
  // Unlocked and locked again: a new parking, reported again.
  stage.on_lock_event("frame", 1, "");
  stage.on_lock_event("frame", 2, "");
  stage.run(env.steady_now());
  EXPECT_EQ(stage.records.size(), 1u);
}

}  // namespace
}  // namespace fleetgw::runtime
