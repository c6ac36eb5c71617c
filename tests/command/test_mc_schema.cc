// The schema side of issue 13: the MC actions are a compatible addition to fleetgw.v1.Command
// (a new oneof, fresh numbers 8-12) and CommandResult (field 11), recorded in the committed
// descriptor snapshot; lock/unlock bytes written by the old schema still parse and mean the same;
// and a gateway of the old schema reading a new MC command sees no lock action (it rejects it
// as malformed instead of acting).
#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <sstream>

#include "tests/command/command_test_util.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::command::testing {
namespace {

namespace pb = google::protobuf;

pb::FileDescriptorSet mc_schema_snapshot() {
  return fleetgw::testing::load_snapshot(FLEETGW_PROTO_SNAPSHOT);
}

const pb::FieldDescriptorProto* mc_schema_field(const pb::FileDescriptorSet& set,
                                                std::string_view message, std::string_view name) {
  return fleetgw::testing::find_field(set, message, name);
}

// The schema before issue 13: Command without 8-12, CommandResult without 11.
pb::FileDescriptorSet mc_schema_before() {
  auto set = fleetgw::testing::current_fleetgw_descriptors();
  for (auto& f : *set.mutable_file()) {
    for (auto& m : *f.mutable_message_type()) {
      auto* fields = m.mutable_field();
      if (m.name() == "Command") {
        fields->erase(std::remove_if(fields->begin(), fields->end(),
                                     [](const auto& fd) { return fd.number() >= 8; }),
                      fields->end());
        // Only the `target` oneof is left.
        while (m.oneof_decl_size() > 1) m.mutable_oneof_decl()->RemoveLast();
      }
      if (m.name() == "CommandResult") {
        fields->erase(std::remove_if(fields->begin(), fields->end(),
                                     [](const auto& fd) { return fd.number() == 11; }),
                      fields->end());
      }
    }
  }
  return set;
}

class McSchemaOldPool {
 public:
  explicit McSchemaOldPool(const pb::FileDescriptorSet& set) {
    const std::string error = fleetgw::testing::build_pool(set, pool_);
    EXPECT_TRUE(error.empty()) << error;
  }
  const pb::Descriptor* type(const std::string& name) const {
    return pool_.FindMessageTypeByName(name);
  }
  std::unique_ptr<pb::Message> make(const pb::Descriptor* d) {
    return std::unique_ptr<pb::Message>(factory_.GetPrototype(d)->New());
  }

 private:
  pb::DescriptorPool pool_;
  pb::DynamicMessageFactory factory_{&pool_};
};

TEST(McActionSchema, AdditionsAreCompatibleAndRecordedInTheSnapshot) {
  const auto current = fleetgw::testing::current_fleetgw_descriptors();
  const auto snapshot = mc_schema_snapshot();
  for (const auto& p : fleetgw::testing::compare(snapshot, current)) ADD_FAILURE() << p;
  const struct {
    const char* message;
    const char* field;
    int number;
  } fields[] = {
      {"Command", "speed_limit", 8},
      {"Command", "assist_level", 9},
      {"Command", "headlight", 10},
      {"Command", "clear_trip", 11},
      {"Command", "power_off", 12},
      {"CommandResult", "mc", 11},
      {"SpeedLimitAction", "kmh", 1},
      {"AssistLevelAction", "level", 1},
      {"HeadlightAction", "on", 1},
      {"McActionResult", "action", 1},
      {"McActionResult", "speed_limit_kmh", 2},
      {"McActionResult", "writes_sent", 7},
      {"McActionResult", "mc_ready", 8},
      {"McActionResult", "obc_ready", 9},
  };
  for (const auto& f : fields) {
    for (const auto* set : {&current, &snapshot}) {
      const auto* d = mc_schema_field(*set, f.message, f.field);
      ASSERT_NE(d, nullptr) << f.message << "." << f.field
                            << (set == &snapshot ? " missing from the committed snapshot" : "");
      EXPECT_EQ(d->number(), f.number) << f.message << "." << f.field;
    }
  }
  // The new actions are one oneof of their own, never part of the lock `target`.
  const auto* speed = mc_schema_field(current, "Command", "speed_limit");
  const auto* kind = mc_schema_field(current, "Command", "lock_kind");
  ASSERT_TRUE(speed->has_oneof_index() && kind->has_oneof_index());
  EXPECT_NE(speed->oneof_index(), kind->oneof_index());
}

TEST(McActionSchema, LockCommandBytesOfTheOldSchemaMeanTheSame) {
  McSchemaOldPool old(mc_schema_before());
  const auto* type = old.type("fleetgw.v1.Command");
  ASSERT_NE(type, nullptr);
  ASSERT_EQ(type->FindFieldByName("speed_limit"), nullptr);
  auto msg = old.make(type);
  const auto* refl = msg->GetReflection();
  refl->SetString(msg.get(), type->FindFieldByName("command_id"), "old-1");
  refl->SetString(msg.get(), type->FindFieldByName("vehicle_id"), kVehicle);
  refl->SetInt64(msg.get(), type->FindFieldByName("issued_at_us"), 1'700'000'000'000'000);
  refl->SetInt64(msg.get(), type->FindFieldByName("expires_at_us"), 1'700'000'060'000'000);
  refl->SetEnumValue(msg.get(), type->FindFieldByName("action"), v1::COMMAND_ACTION_UNLOCK);
  refl->SetString(msg.get(), type->FindFieldByName("lock_kind"), "battery");
  const std::string bytes = msg->SerializeAsString();

  v1::Command now;
  ASSERT_TRUE(now.ParseFromString(bytes));
  EXPECT_EQ(now.action(), v1::COMMAND_ACTION_UNLOCK);
  EXPECT_EQ(now.target_case(), v1::Command::kLockKind);
  EXPECT_EQ(now.lock_kind(), "battery");
  EXPECT_EQ(now.mc_action_case(), v1::Command::MC_ACTION_NOT_SET);
  // The same bytes as the new schema writes for the same command.
  auto fresh = make_command(kVehicle, "battery", "unlock", Micros(1'700'000'000'000'000),
                            Micros(1'700'000'060'000'000), "old-1");
  ASSERT_TRUE(fresh.has_value());
  EXPECT_EQ(fresh->SerializeAsString(), bytes);

  // And the gateway executes those old bytes as an unlock of the battery lock.
  Rig rig;
  rig.bus.run_for(2s);
  auto cmd =
      make_command(kVehicle, "battery", "unlock", rig.bus.now(), rig.bus.now() + 60s, "old-2");
  const auto* r = rig.run(sign_command(*cmd, rig.key, kKeyId));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_FALSE(r->has_mc());
  EXPECT_EQ(r->locks_size(), 1);
}

TEST(McActionSchema, AnOldGatewaySeesNoLockActionInANewCommand) {
  McSchemaOldPool old(mc_schema_before());
  const auto* type = old.type("fleetgw.v1.Command");
  ASSERT_NE(type, nullptr);
  auto cmd = make_mc_command(kVehicle, "speed_limit", "15", Micros(1'700'000'000'000'000),
                             Micros(1'700'000'060'000'000), "new-1");
  ASSERT_TRUE(cmd.has_value());
  auto msg = old.make(type);
  ASSERT_TRUE(msg->ParseFromString(cmd->SerializeAsString()));
  const auto* refl = msg->GetReflection();
  // The old verifier requires LOCK or UNLOCK and a target: the command is malformed to it.
  EXPECT_EQ(refl->GetEnumValue(*msg, type->FindFieldByName("action")),
            v1::COMMAND_ACTION_UNSPECIFIED);
  EXPECT_FALSE(refl->HasField(*msg, type->FindFieldByName("lock_kind")));
  EXPECT_FALSE(refl->HasField(*msg, type->FindFieldByName("whole_vehicle")));

  // An old reader of results parses a new MC result (field 11 unknown, the rest intact).
  v1::CommandResult r;
  r.set_command_id("new-1");
  r.set_result(v1::COMMAND_RESULT_CODE_FAILED);
  r.set_reason("not_confirmed: x");
  r.mutable_mc()->set_action("speed_limit");
  r.mutable_mc()->set_speed_limit_kmh(25);
  const auto* rtype = old.type("fleetgw.v1.CommandResult");
  ASSERT_NE(rtype, nullptr);
  auto old_result = old.make(rtype);
  ASSERT_TRUE(old_result->ParseFromString(r.SerializeAsString()));
  EXPECT_EQ(old_result->GetReflection()->GetString(*old_result, rtype->FindFieldByName("reason")),
            "not_confirmed: x");
}

}  // namespace
}  // namespace fleetgw::command::testing
