// The geofence's say over lock commands (issue 14, CommandService::set_lock_guard): a lock the
// guard refuses ends `rejected` with reason no_parking_zone and its detail, and nothing is written
// to the bus; the guard is told whether the lock ends a ride (whole vehicle, frame, wheel) and is
// never asked about an unlock.
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

TEST(LockGuard, ARefusedRideEndingLockIsRejectedAsNoParkingZoneWithoutTouchingTheBus) {
  Rig rig;
  rig.bus.run_for(2s);
  std::vector<bool> asked;  // ride_ending of every call
  rig.service->set_lock_guard([&](bool ride_ending, Micros) -> std::optional<std::string> {
    asked.push_back(ride_ending);
    if (!ride_ending) return std::nullopt;
    return std::string("will not end the ride inside the no-parking zone 'station'");
  });

  // Unlock the frame first: an unlock is never judged.
  const auto* u = rig.run(rig.payload("frame", "unlock"));
  ASSERT_NE(u, nullptr);
  EXPECT_EQ(u->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << u->reason();
  EXPECT_TRUE(asked.empty());

  const Micros t0 = rig.bus.now();
  const auto* l = rig.run(rig.payload("frame", "lock"));
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(l->reason(),
            "no_parking_zone: will not end the ride inside the no-parking zone "
            "'station'");
  EXPECT_EQ(rig.sender.lock_writes(-1, t0), 0u) << "refused before the bus";
  EXPECT_EQ(rig.lock_state(1), sim::LockState::kUnlocked);
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_TRUE(asked[0]) << "the frame lock ends a ride";

  // The seat lock does not end a ride: asked, allowed, executed.
  const auto* s = rig.run(rig.payload("seat", "unlock"));
  ASSERT_NE(s, nullptr);
  const auto* sl = rig.run(rig.payload("seat", "lock"));
  ASSERT_NE(sl, nullptr);
  EXPECT_EQ(sl->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << sl->reason();
  ASSERT_EQ(asked.size(), 2u);
  EXPECT_FALSE(asked[1]);

  // The whole vehicle ends a ride.
  const auto* v = rig.run(rig.payload("vehicle", "lock"));
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(v->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  ASSERT_EQ(asked.size(), 3u);
  EXPECT_TRUE(asked[2]);
}

}  // namespace
}  // namespace fleetgw::command::testing
