// Malformed MC commands (issue 24): a genuinely signed Command carrying two MC actions (protobuf
// would keep the last one and run it), a speed_limit without its value and a speed_limit of 0
// (the same bytes in proto3) are refused as malformed, and nothing reaches the MC.
#include <gtest/gtest.h>

#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

// A SignedCommand over exactly `command_bytes` (which need not be one serialized Command).
std::string sign_bytes(const Rig& rig, const std::string& command_bytes) {
  v1::SignedCommand s;
  s.set_command(command_bytes);
  const auto sig = rig.key.sign(
      {reinterpret_cast<const std::uint8_t*>(command_bytes.data()), command_bytes.size()});
  s.set_signature(std::string(sig.begin(), sig.end()));
  s.set_key_id(kKeyId);
  return s.SerializeAsString();
}

v1::Command base_command(const Rig& rig, const std::string& id) {
  v1::Command c;
  c.set_command_id(id);
  c.set_vehicle_id(kVehicle);
  c.set_issued_at_us(rig.bus.now().count());
  c.set_expires_at_us((rig.bus.now() + 60s).count());
  return c;
}

TEST(McMalformed, ACommandCarryingTwoMcActionsIsRefusedAndNeitherRuns) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  // "limit 15" then "power off" in one signed Command: a parse keeps only power_off.
  v1::Command limit = base_command(rig, "two-actions");
  limit.mutable_speed_limit()->set_kmh(15);
  v1::Command off;
  off.mutable_power_off();
  const auto* r = rig.run(sign_bytes(rig, limit.SerializeAsString() + off.SerializeAsString()));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "malformed") << r->reason();
  EXPECT_NE(r->reason().find("more than one MC action (speed_limit, power_off)"), std::string::npos)
      << r->reason();
  // The same action twice ("limit 25", then "limit 10": the last would win) is refused too.
  v1::Command first = base_command(rig, "same-twice");
  first.mutable_speed_limit()->set_kmh(25);
  v1::Command second;
  second.mutable_speed_limit()->set_kmh(10);
  const auto* twice =
      rig.run(sign_bytes(rig, first.SerializeAsString() + second.SerializeAsString()));
  ASSERT_NE(twice, nullptr);
  EXPECT_EQ(reason_code(*twice), "malformed") << twice->reason();
  rig.bus.run_for(2s);
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
  EXPECT_EQ(rig.sender.frames(0x760, kIotFnShutdown, t0), 0u);
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, 0);
  // One action per command still runs.
  const auto* ok = rig.run(rig.mc_payload("speed_limit", "15"));
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << ok->reason();
}

TEST(McMalformed, ASpeedLimitWithoutAValueOrOfZeroIsRefusedAndNothingIsWritten) {
  Rig rig;
  rig.bus.run_for(2s);
  const Micros t0 = rig.bus.now();
  // `speed_limit {}`: the action without its value.
  v1::Command empty = base_command(rig, "no-value");
  empty.mutable_speed_limit();
  const auto* r = rig.run(sign_bytes(rig, empty.SerializeAsString()));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "malformed") << r->reason();
  EXPECT_NE(r->reason().find("speed_limit without kmh"), std::string::npos) << r->reason();
  // kmh 0 written explicitly on the wire (field 8 { field 1 = 0 }): the same refusal.
  const std::string explicit_zero =
      base_command(rig, "zero").SerializeAsString() + std::string("\x42\x02\x08\x00", 4);
  v1::Command parsed;
  ASSERT_TRUE(parsed.ParseFromString(explicit_zero));
  ASSERT_TRUE(parsed.has_speed_limit());
  const auto* zero = rig.run(sign_bytes(rig, explicit_zero));
  ASSERT_NE(zero, nullptr);
  EXPECT_EQ(reason_code(*zero), "malformed") << zero->reason();
  // The operator's tool refuses 0 before signing anything.
  EXPECT_FALSE(make_mc_command(kVehicle, "speed_limit", "0", rig.bus.now(), rig.bus.now() + 60s,
                               "tool-zero"));
  rig.bus.run_for(2s);
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, 0);
  // Never a 0 from the gateway's own writes either: refused before the bus as out_of_range.
  McRequest own;
  own.kind = McActionKind::kSpeedLimit;
  own.speed_limit_kmh = 0;
  const auto refused =
      rig.service->start_own_mc_action(own, rig.bus.now(), [](bool, std::string, Micros) {});
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->reason, RejectReason::kOutOfRange) << refused->detail;
  EXPECT_EQ(rig.sender.mc_writes(0, t0), 0u);
}

}  // namespace
}  // namespace fleetgw::command::testing
