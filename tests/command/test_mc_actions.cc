// MC actions (issue 13) in lockstep against the simulated bike: each is confirmed from the bus
// (settings read back, running data, READY replies), an MC that ignores writes gives `failed`,
// a silent MC `timeout`, refusals put nothing on the bus, and the new actions go through the
// same authentication, freshness and replay checks as lock commands.
#include <gtest/gtest.h>

#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

constexpr uint8_t kMcFnAssist = 0x30;
constexpr uint8_t kMcFnSettings = 0x34;
constexpr uint8_t kMcFnClear = 0x36;

sim::RideSegment mc_leg(double duration_s, double speed_kmh) {
  sim::RideSegment s;
  s.duration_s = duration_s;
  s.speed_kmh = speed_kmh;
  return s;
}

// A bike that rides for `ride_s` at `kmh`, then stands.
sim::Scenario mc_ride_scenario(double ride_s, double kmh) {
  auto sc = quiet_scenario();
  sc.locks_locked = false;
  sc.ride.push_back(mc_leg(ride_s, kmh));
  sc.ride.push_back(mc_leg(3600, 0));
  return sc;
}

sim::Scenario mc_ignoring_scenario() {
  auto sc = quiet_scenario();
  sc.mc_ignores_writes = true;
  return sc;
}

TEST(McActions, SpeedLimitIsWrittenAsAnOffsetAndConfirmedByReadingBack) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("speed_limit", "15"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(r->mc().action(), "speed_limit");
  EXPECT_EQ(r->mc().speed_limit_kmh(), 15u);
  EXPECT_EQ(r->mc().factory_speed_limit_kmh(), 25u);
  EXPECT_EQ(r->mc().writes_sent(), 1u);
  EXPECT_FALSE(r->command_sha256().empty());
  // The simulated MC really took the spec's offset (25 - 10 = 15).
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, -10);
  // One write, and a settings read on each side of it.
  EXPECT_EQ(rig.sender.mc_writes(kMcFnSettings, t0), 1u);
  EXPECT_GE(rig.sender.frames(0x761, 0x33, t0), 2u);
  // The journal says succeeded.
  const auto entry = rig.store->command(r->command_id());
  ASSERT_TRUE(entry.has_value());
  EXPECT_EQ(entry->state, "succeeded");
}

TEST(McActions, SpeedLimitCapsTheSimulatedSpeed) {
  Rig rig(mc_ride_scenario(600, 25));
  rig.bus.run_for(20s);
  ASSERT_GT(rig.bus.bike().state().speed_kmh, 20.0);
  const auto* r = rig.run(rig.mc_payload("speed_limit", "12"));
  ASSERT_NE(r, nullptr);
  ASSERT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  // T13's numbers: factory 25 km/h, limit 12 -> offset -13.
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, -13);
  rig.bus.run_for(20s);
  EXPECT_LE(rig.bus.bike().state().speed_kmh, 12.5);
}

TEST(McActions, OutOfRangeSpeedLimitIsRejectedWithNothingWritten) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("speed_limit", "30"));  // above the factory 25
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "out_of_range") << r->reason();
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, 0);

  // A faster bike: its range is 60 - 50 .. 60 km/h.
  auto sc = quiet_scenario();
  sc.speed_limit_kmh = 60;
  Rig fast(sc);
  fast.bus.run_for(2s);
  const Micros t1 = fast.bus.now();
  const auto* low = fast.run(fast.mc_payload("speed_limit", "9"));
  ASSERT_NE(low, nullptr);
  EXPECT_EQ(reason_code(*low), "out_of_range") << low->reason();
  EXPECT_EQ(fast.sender.mc_writes(0, t1), 0u);
  const auto* ok = fast.run(fast.mc_payload("speed_limit", "10"));
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << ok->reason();
  EXPECT_EQ(fast.bus.bike().state().speed_limit_offset_kmh, -50);
}

TEST(McActions, AssistLevelIsConfirmedByTheRunningData) {
  Rig rig;
  rig.bus.run_for(2s);
  ASSERT_EQ(rig.bus.bike().state().assist, 2);  // norm
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("assist_level", "eco"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(r->mc().assist_level(), "eco");
  EXPECT_FALSE(r->mc().headlight_on());
  EXPECT_EQ(rig.bus.bike().state().assist, 1);
  EXPECT_FALSE(rig.bus.bike().state().headlight);  // the other half kept
  EXPECT_EQ(rig.sender.mc_writes(kMcFnAssist, t0), 1u);
}

TEST(McActions, HeadlightIsConfirmedByTheRunningDataAndKeepsTheAssistLevel) {
  Rig rig;
  rig.bus.run_for(2s);
  const auto* on = rig.run(rig.mc_payload("headlight", "on"));
  ASSERT_NE(on, nullptr);
  EXPECT_EQ(on->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << on->reason();
  EXPECT_TRUE(on->mc().headlight_on());
  EXPECT_TRUE(rig.bus.bike().state().headlight);
  EXPECT_EQ(rig.bus.bike().state().assist, 2);
  const auto* off = rig.run(rig.mc_payload("headlight", "off"));
  ASSERT_NE(off, nullptr);
  EXPECT_EQ(off->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << off->reason();
  EXPECT_FALSE(rig.bus.bike().state().headlight);
}

TEST(McActions, ClearTripIsConfirmedByTheTripCounters) {
  Rig rig(mc_ride_scenario(150, 20));
  rig.bus.run_for(170s);
  ASSERT_GT(rig.bus.bike().state().trip_m, 500.0);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("clear_trip"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(r->mc().trip_m(), 0u);
  EXPECT_LT(rig.bus.bike().state().trip_m, 1.0);
  EXPECT_EQ(rig.sender.mc_writes(kMcFnClear, t0), 1u);
}

TEST(McActions, AnMcThatIgnoresWritesGivesFailedNeverSucceeded) {
  Rig rig(mc_ignoring_scenario());
  rig.bus.run_for(2s);
  const auto* limit = rig.run(rig.mc_payload("speed_limit", "15"));
  ASSERT_NE(limit, nullptr);
  EXPECT_EQ(limit->result(), v1::COMMAND_RESULT_CODE_FAILED) << limit->reason();
  EXPECT_EQ(reason_code(*limit), "not_confirmed") << limit->reason();
  EXPECT_EQ(limit->mc().writes_sent(), 2u);  // the write, then one repeat (retries = 1)
  EXPECT_EQ(limit->mc().speed_limit_kmh(), 25u);
  const std::string limit_id = limit->command_id();  // `limit` dangles once results grow

  const auto* assist = rig.run(rig.mc_payload("assist_level", "turbo"));
  ASSERT_NE(assist, nullptr);
  EXPECT_EQ(assist->result(), v1::COMMAND_RESULT_CODE_FAILED) << assist->reason();
  EXPECT_EQ(reason_code(*assist), "not_confirmed");
  EXPECT_EQ(assist->mc().assist_level(), "norm");

  const auto* light = rig.run(rig.mc_payload("headlight", "on"));
  ASSERT_NE(light, nullptr);
  EXPECT_EQ(light->result(), v1::COMMAND_RESULT_CODE_FAILED) << light->reason();
  EXPECT_EQ(rig.sender.mc_writes(kMcFnAssist), 4u);  // two attempts each

  const auto entry = rig.store->command(limit_id);
  ASSERT_TRUE(entry.has_value());
  EXPECT_EQ(entry->state, "failed");
}

TEST(McActions, ClearTripIgnoredByTheMcFails) {
  auto sc = mc_ride_scenario(150, 20);
  sc.mc_ignores_writes = true;
  Rig rig(sc);
  rig.bus.run_for(170s);
  const auto* r = rig.run(rig.mc_payload("clear_trip"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_FAILED) << r->reason();
  EXPECT_EQ(reason_code(*r), "not_confirmed");
  EXPECT_GT(r->mc().trip_m(), 500u);
}

TEST(McActions, AnMcThatStopsAnsweringGivesTimeout) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent silence;
  silence.at = 3s;
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kMc;  // still "online" for a while: the read goes out
  sc.events.push_back(silence);
  Rig rig(sc);
  rig.bus.run_for(3100ms);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("speed_limit", "20"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_TIMEOUT) << r->reason();
  EXPECT_EQ(reason_code(*r), "no_answer");
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);  // never written without a fresh read
}

TEST(McActions, RefusalsPutNothingOnTheBus) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* unknown = rig.run(rig.mc_payload("assist_level", "warp\nspeed"));
  ASSERT_NE(unknown, nullptr);
  EXPECT_EQ(reason_code(*unknown), "unknown_assist_level") << unknown->reason();
  EXPECT_EQ(unknown->reason().find('\n'), std::string::npos);

  // An MC action that also carries a lock action: an older gateway would lock. Malformed.
  v1::Command mixed =
      *make_mc_command(kVehicle, "power_off", {}, rig.bus.now(), rig.bus.now() + 60s, "mixed-1");
  mixed.set_action(v1::COMMAND_ACTION_UNLOCK);
  const auto* m = rig.run(sign_command(mixed, rig.key, kKeyId));
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(reason_code(*m), "malformed") << m->reason();
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
  EXPECT_EQ(rig.sender.frames(0x760, kIotFnShutdown, t0), 0u);
}

TEST(McActions, SilentMcIsRefusedAsOffline) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent silence;
  silence.at = 1s;
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kMc;
  sc.events.push_back(silence);
  Rig rig(sc);
  rig.bus.run_for(10s);
  const Micros t0 = rig.bus.now();
  for (const auto& [action, value] : std::vector<std::pair<std::string, std::string>>{
           {"speed_limit", "15"}, {"assist_level", "eco"}, {"clear_trip", ""}}) {
    const auto* r = rig.run(rig.mc_payload(action, value));
    ASSERT_NE(r, nullptr) << action;
    EXPECT_EQ(reason_code(*r), "mc_offline") << action << ": " << r->reason();
  }
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
}

TEST(McActions, PowerOffIsConfirmedByTheReadyReplies) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("power_off"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_TRUE(r->mc().mc_ready());
  EXPECT_TRUE(r->mc().has_obc_ready() && r->mc().obc_ready());
  EXPECT_GE(rig.sender.frames(0x760, kIotFnShutdown, t0), 1u);
  rig.bus.run_for(3s);
  EXPECT_FALSE(rig.bus.bike().state().powered);
}

TEST(McActions, PowerOffIsRefusedWhileTheBikeMoves) {
  Rig rig(mc_ride_scenario(600, 20));
  rig.bus.run_for(20s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.mc_payload("power_off"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "interlock_moving") << r->reason();
  EXPECT_EQ(rig.sender.frames(0x760, kIotFnShutdown, t0), 0u);
  rig.bus.run_for(3s);
  EXPECT_TRUE(rig.bus.bike().state().powered);
}

TEST(McActions, PowerOffIsRefusedWhileALockMoves) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  rig.service->on_payload(rig.payload("seat", "unlock"), rig.bus.now());
  ASSERT_TRUE(rig.service->busy());
  const auto* r = rig.run(rig.mc_payload("power_off"));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "lock_moving") << r->reason();
  EXPECT_EQ(rig.sender.frames(0x760, kIotFnShutdown, t0), 0u);
}

TEST(McActions, NewActionsAreCheckedLikeLockCommands) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  // Expired while waiting in the broker.
  const auto* expired = rig.run(rig.mc_payload("speed_limit", "15", {}, -1s, rig.bus.now() - 120s));
  ASSERT_NE(expired, nullptr);
  EXPECT_EQ(reason_code(*expired), "expired") << expired->reason();
  // A broken signature over genuine bytes: rejected, bound to the forged payload only.
  const std::string genuine = rig.mc_payload("power_off");
  const auto* forged = rig.run(broken_copy(genuine));
  ASSERT_NE(forged, nullptr);
  EXPECT_EQ(reason_code(*forged), "signature_invalid");
  EXPECT_TRUE(forged->command_sha256().empty());
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
  EXPECT_EQ(rig.sender.frames(0x760, kIotFnShutdown, t0), 0u);

  // Accepted once; a redelivery never writes again; the id reused for another value is refused.
  const std::string limit = rig.mc_payload("speed_limit", "18", "limit-1");
  const auto* first = rig.run(limit);
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(first->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << first->reason();
  const std::size_t writes = rig.sender.mc_writes(kMcFnSettings);
  const std::size_t before = rig.results.size();
  rig.service->on_payload(limit, rig.bus.now());
  rig.bus.run_for(3s);
  ASSERT_GT(rig.results.size(), before);
  EXPECT_TRUE(rig.resent_flags.back());
  EXPECT_EQ(rig.results.back().result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  const auto* reused = rig.run(rig.mc_payload("speed_limit", "10", "limit-1"));
  ASSERT_NE(reused, nullptr);
  EXPECT_EQ(reason_code(rig.results.back()), "replayed") << rig.results.back().reason();
  EXPECT_EQ(rig.sender.mc_writes(kMcFnSettings), writes);
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, -7);
}

}  // namespace
}  // namespace fleetgw::command::testing
