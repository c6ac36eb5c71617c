// Commands executed against the simulated bike in lockstep: the lock really moves, failures and
// silence give definite results, interlocks hold, and nothing is ever actuated twice.
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

const auto& kinds() {
  static const std::vector<std::pair<std::string, int>> k{
      {"seat", 0}, {"frame", 1}, {"steering", 2}, {"battery", 3}, {"other", 4}};
  return k;
}

TEST(Execution, UnlockAndLockEveryLockKindReallyMovesTheLock) {
  Rig rig;
  rig.bus.run_for(2s);
  for (const auto& [kind, k] : kinds()) {
    ASSERT_EQ(rig.lock_state(k), sim::LockState::kLocked) << kind;
    const Micros t0 = rig.bus.now();
    const auto* u = rig.run(rig.payload(kind, "unlock"));
    ASSERT_NE(u, nullptr) << kind;
    EXPECT_EQ(u->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << kind << ": " << u->reason();
    EXPECT_EQ(u->final_lock_state(), v1::LOCK_STATE_UNLOCKED) << kind;
    EXPECT_EQ(u->final_lock_state_name(), "unlocked") << kind;
    EXPECT_EQ(rig.lock_state(k), sim::LockState::kUnlocked) << kind;
    EXPECT_GT(u->duration_ms(), 0u);
    EXPECT_LT(u->duration_ms(), 3000u);
    EXPECT_EQ(rig.sender.lock_writes(k, t0), 1u) << kind;
    EXPECT_EQ(rig.sender.lock_writes(-1, t0), 1u) << kind << ": only this lock was written";
    ASSERT_EQ(u->locks_size(), 1);
    EXPECT_EQ(u->locks(0).lock_kind(), kind);

    const auto* l = rig.run(rig.payload(kind, "lock"));
    ASSERT_NE(l, nullptr) << kind;
    EXPECT_EQ(l->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << kind << ": " << l->reason();
    EXPECT_EQ(l->final_lock_state(), v1::LOCK_STATE_LOCKED) << kind;
    EXPECT_EQ(rig.lock_state(k), sim::LockState::kLocked) << kind;
  }
  EXPECT_EQ(rig.service->stats().succeeded, 10u);
  // Every result is in the outbox at priority 0 (command_result), journal entries final.
  std::uint64_t p0 = 0;
  for (const auto& d : rig.store->outbox_depth()) {
    if (d.priority == 0) p0 = d.entries;
  }
  EXPECT_EQ(p0, 10u);
  for (const auto& r : rig.results) {
    const auto e = rig.store->command(r.command_id());
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->state, "succeeded");
  }
}

TEST(Execution, LockEventsCarryTheCommandCause) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string p = rig.payload("battery", "unlock", "cmd-cause");
  const auto* r = rig.run(p);
  ASSERT_NE(r, nullptr);
  ASSERT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  rig.bus.run_for(1s);
  bool found = false;
  for (const auto& l : rig.sink.batch().locks) {
    if (l.record.kind == "battery" && l.record.new_state == "unlocked") {
      EXPECT_EQ(l.record.cause, "command:cmd-cause");
      found = true;
    }
  }
  EXPECT_TRUE(found) << "no battery lock event";
}

TEST(Execution, JammedLockFails) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent jam;
  jam.action = sim::Action::kJamLock;
  jam.node = motinova::Node::kLock1;  // seat
  sc.events.push_back(jam);
  Rig rig(sc);
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.payload("seat", "unlock"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_FAILED) << r->reason();
  EXPECT_EQ(reason_code(*r), "lock_failed") << r->reason();
  EXPECT_EQ(r->final_lock_state_name(), "unlock_failed");
  EXPECT_EQ(r->final_lock_state(), v1::LOCK_STATE_FAULT);
  // A reported failure is not retried: a jammed bolt is not forced.
  EXPECT_EQ(rig.sender.lock_writes(0, t0), 1u);
  EXPECT_EQ(rig.store->command(r->command_id())->state, "failed");
}

TEST(Execution, SilentLockTimesOutWithinTheConfiguredTime) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent silence;
  silence.at = 3s;
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kLock3;  // steering goes quiet; still "online" for 3 s
  sc.events.push_back(silence);
  Rig rig(sc);
  rig.tweak = [](CommandServiceConfig& c) {
    c.confirm_timeout = 1500ms;
    c.retries = 1;
  };
  rig.make_service();
  rig.bus.run_for(3200ms);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.payload("steering", "unlock"), 10s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_TIMEOUT) << r->reason();
  EXPECT_EQ(reason_code(*r), "no_confirmation") << r->reason();
  // Two attempts of 1.5 s; the result is there within them (plus one tick).
  EXPECT_GE(r->duration_ms(), 3000u);
  EXPECT_LE(r->duration_ms(), 3100u);
  EXPECT_GE(rig.sender.lock_writes(2, t0), 2u);  // one per attempt (plus repeats of lost events)
  EXPECT_EQ(rig.store->command(r->command_id())->state, "timeout");
}

sim::RideSegment segment(double duration_s, double speed_kmh) {
  sim::RideSegment s;
  s.duration_s = duration_s;
  s.speed_kmh = speed_kmh;
  return s;
}

sim::Scenario riding() {
  auto sc = quiet_scenario();
  sc.locks_locked = false;
  sc.ride.push_back(segment(600, 20));
  return sc;
}

TEST(Execution, MovingBikeRefusesFrameLockAndBatteryUnlock) {
  Rig rig(riding());
  rig.bus.run_for(30s);
  ASSERT_GT(rig.bus.bike().state().speed_kmh, 10);
  const Micros t0 = rig.bus.now();
  for (const auto& [kind, action] : std::vector<std::pair<std::string, std::string>>{
           {"frame", "lock"}, {"steering", "lock"}, {"battery", "unlock"}, {"vehicle", "lock"}}) {
    const auto* r = rig.run(rig.payload(kind, action), 2s);
    ASSERT_NE(r, nullptr) << kind;
    EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED) << kind;
    EXPECT_EQ(reason_code(*r), "interlock_moving") << kind << ": " << r->reason();
  }
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  EXPECT_EQ(rig.lock_state(1), sim::LockState::kUnlocked);
  // Not guarded: the seat lock may lock while riding.
  const auto* seat = rig.run(rig.payload("seat", "lock"));
  ASSERT_NE(seat, nullptr);
  EXPECT_EQ(seat->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << seat->reason();
}

TEST(Execution, MotorTurningRecentlyCountsAsMoving) {
  // The bike stops at 30 s; with a 5 s motor window the frame lock stays refused for a while.
  auto sc = quiet_scenario();
  sc.locks_locked = false;
  sc.ride.push_back(segment(30, 20));
  sc.ride.push_back(segment(600, 0));
  Rig rig(sc);
  rig.tweak = [](CommandServiceConfig& c) { c.interlock_motor_window = 120s; };
  rig.make_service();
  rig.bus.run_for(60s);
  ASSERT_LT(rig.bus.bike().state().speed_kmh, 0.1);
  const auto* r = rig.run(rig.payload("frame", "lock"), 2s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "interlock_moving") << r->reason();
  rig.bus.run_for(120s);
  const auto* ok = rig.run(rig.payload("frame", "lock"));
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << ok->reason();
}

TEST(Execution, DuplicateDeliveryDoesNotActuateTwice) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const std::string p = rig.payload("frame", "unlock", "cmd-dup");
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kStarted);
  rig.bus.run_for(50ms);
  // QoS-1 redelivery while executing: ignored.
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kDuplicateInProgress);
  rig.bus.run_for(3s);
  ASSERT_EQ(rig.results.size(), 1u);
  EXPECT_EQ(rig.results[0].result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  // After it finished: the stored result again, no second actuation.
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kDuplicateAnswered);
  rig.bus.run_for(3s);
  ASSERT_EQ(rig.results.size(), 2u);
  EXPECT_TRUE(rig.resent_flags[1]);
  EXPECT_EQ(rig.results[1].result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  EXPECT_EQ(rig.results[1].final_lock_state_name(), "unlocked");
  EXPECT_EQ(rig.sender.lock_writes(-1, t0), 1u);
  EXPECT_EQ(rig.service->stats().duplicates, 2u);
  // Even after a restart (journal in SQLite).
  rig.restart();
  EXPECT_EQ(rig.service->recover(rig.bus.now()), 0u);
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kDuplicateAnswered);
  rig.bus.run_for(3s);
  EXPECT_EQ(rig.sender.lock_writes(-1, t0), 1u);
}

TEST(Execution, RestartMidCommandNeverActuatesTwiceAndEndsDefinite) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const std::string p = rig.payload("battery", "unlock", "cmd-crash");
  ASSERT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kStarted);
  rig.bus.run_for(100ms);
  ASSERT_EQ(rig.sender.lock_writes(3, t0), 1u);
  ASSERT_TRUE(rig.results.empty());
  ASSERT_EQ(rig.store->command("cmd-crash")->state, "executing");

  rig.restart();  // the service, node and store die with the command in flight
  const Micros t1 = rig.bus.now();
  EXPECT_EQ(rig.service->recover(rig.bus.now()), 1u);
  ASSERT_EQ(rig.results.size(), 1u);
  EXPECT_EQ(rig.results[0].command_id(), "cmd-crash");
  EXPECT_EQ(rig.results[0].result(), v1::COMMAND_RESULT_CODE_TIMEOUT);
  EXPECT_EQ(reason_code(rig.results[0]), "interrupted_by_restart");
  EXPECT_EQ(rig.store->command("cmd-crash")->state, "timeout");
  // The broker redelivers the command after the restart: answered, not acted on.
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kDuplicateAnswered);
  rig.bus.run_for(5s);
  EXPECT_EQ(rig.sender.lock_writes(-1, t1), 0u);
  EXPECT_EQ(rig.results.back().result(), v1::COMMAND_RESULT_CODE_TIMEOUT);
  // recover() is idempotent.
  EXPECT_EQ(rig.service->recover(rig.bus.now()), 0u);
}

TEST(Execution, CommandExpiredWhileOfflineIsRejected) {
  Rig rig;
  rig.bus.run_for(2s);
  // Issued with 30 s validity, delivered two minutes later when the gateway is back.
  const std::string p = rig.payload("seat", "unlock", {}, 30s);
  rig.bus.run_for(120s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(p, 2s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "expired") << r->reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kLocked);
  // Redelivered again: the same answer, not a second judgement.
  EXPECT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kDuplicateAnswered);
}

// The simulator at sim.speed > 1 (or a replayed log) runs the bus timeline away from the wall
// clock; commands carry wall-clock times and must be judged by the wall clock.
TEST(Execution, FreshnessFollowsTheWallClockNotTheBusTimeline) {
  Micros wall{0};
  auto make_rig = [&wall] {
    auto rig = std::make_unique<Rig>(quiet_scenario(), /*start_service=*/false);
    wall = rig->bus.now();
    rig->wall_clock = [&wall] { return wall; };
    rig->make_service();
    return rig;
  };
  auto signed_at_wall = [&wall](Rig& rig, std::string_view action, Micros expires_in) {
    auto cmd = make_command(kVehicle, "seat", action, wall, wall + expires_in, random_command_id());
    return sign_command(*cmd, rig.key, kKeyId);
  };
  {
    // Bus 30 minutes ahead of the wall clock (accelerated simulation): still fresh.
    auto rig = make_rig();
    rig->bus.run_for(1800s);
    wall += 2s;
    const auto* r = rig->run(signed_at_wall(*rig, "unlock", 60s));
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
    EXPECT_EQ(rig->lock_state(0), sim::LockState::kUnlocked);
  }
  {
    // The wall clock passed the expiry while the bus timeline barely moved: expired.
    auto rig = make_rig();
    rig->bus.run_for(2s);
    const std::string p = signed_at_wall(*rig, "unlock", 30s);
    wall += 120s;
    const Micros t0 = rig->bus.now();
    const auto* r = rig->run(p, 2s);
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(reason_code(*r), "expired") << r->reason();
    EXPECT_EQ(rig->sender.command_frames_since(t0), 0u);
    EXPECT_EQ(rig->lock_state(0), sim::LockState::kLocked);
  }
}

TEST(Execution, WholeVehicleUnlockAndLockInRentalOrder) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* u = rig.run(rig.payload("vehicle", "unlock"), 20s);
  ASSERT_NE(u, nullptr);
  EXPECT_EQ(u->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << u->reason();
  for (int k = 0; k < 5; ++k) EXPECT_EQ(rig.lock_state(k), sim::LockState::kUnlocked) << k;
  EXPECT_FALSE(rig.bus.bike().state().vehicle_locked);
  ASSERT_EQ(u->locks_size(), 5);
  EXPECT_EQ(u->locks(0).lock_kind(), "frame");  // the wheel is free first at rental start
  // The vehicle UNLOCK broadcast precedes the first lock write.
  Micros first_unlock_bc = Micros::max(), first_write = Micros::max();
  for (const auto& s : rig.sender.sent) {
    if (s.at < t0) continue;
    if (s.frame.can_id == 0x760 && s.frame.function == 0x12)
      first_unlock_bc = std::min(first_unlock_bc, s.at);
    if (s.frame.can_id >= 0x767 && s.frame.can_id <= 0x76B)
      first_write = std::min(first_write, s.at);
  }
  EXPECT_LE(first_unlock_bc, first_write);

  const Micros t1 = rig.bus.now();
  const auto* l = rig.run(rig.payload("vehicle", "lock"), 20s);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << l->reason();
  for (int k = 0; k < 5; ++k) EXPECT_EQ(rig.lock_state(k), sim::LockState::kLocked) << k;
  EXPECT_TRUE(rig.bus.bike().state().vehicle_locked);
  ASSERT_EQ(l->locks_size(), 5);
  EXPECT_EQ(l->locks(0).lock_kind(), "seat");
  EXPECT_EQ(l->locks(1).lock_kind(), "battery");
  EXPECT_EQ(l->locks(4).lock_kind(), "frame");  // frame last at rental end
  // The vehicle LOCK broadcast comes after the last lock write.
  Micros last_write{0}, lock_bc = Micros::max();
  for (const auto& s : rig.sender.sent) {
    if (s.at < t1) continue;
    if (s.frame.can_id >= 0x767 && s.frame.can_id <= 0x76B) {
      const int f = s.frame.function - node::ids::lock_function_base(s.frame.can_id - 0x767);
      if (f == 2) last_write = std::max(last_write, s.at);
    }
    if (s.frame.can_id == 0x760 && s.frame.function == 0x11) lock_bc = std::min(lock_bc, s.at);
  }
  EXPECT_LT(last_write, lock_bc);
  EXPECT_EQ(rig.sender.lock_writes(-1, t1), 5u);
}

TEST(Execution, BusyLockIsRefused) {
  Rig rig;
  rig.bus.run_for(2s);
  ASSERT_EQ(rig.service->on_payload(rig.payload("seat", "unlock"), rig.bus.now()),
            Disposition::kStarted);
  const auto* r = rig.run(rig.payload("seat", "lock"), 1s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "lock_busy") << r->reason();
  const auto* v = rig.run(rig.payload("vehicle", "lock"), 1s);
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(reason_code(*v), "lock_busy") << v->reason();
}

TEST(Execution, ServiceDestroyedMidCommandLeavesNodeCallbacksHarmless) {
  Rig rig;
  rig.bus.run_for(2s);
  ASSERT_EQ(rig.service->on_payload(rig.payload("seat", "unlock"), rig.bus.now()),
            Disposition::kStarted);
  rig.bus.run_for(50ms);
  rig.forwarder.service = nullptr;
  rig.service.reset();  // the node (still alive) will call back when the lock confirms
  rig.bus.run_for(3s);  // must not crash (ASan)
  SUCCEED();
}

}  // namespace
}  // namespace fleetgw::command::testing
