// Schema v1.3 (issue 13): the retained VehicleState (proto/fleetgw/v1/state.proto) is a
// compatible addition recorded in the committed descriptor snapshot with its numbers (so a later
// removal or renumbering is caught by ProtoCompat), and it reaches the wire as Envelope body 20.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::uplink {
namespace {

namespace pb = google::protobuf;

pb::FileDescriptorSet state_snapshot() {
  return testing::load_snapshot(FLEETGW_PROTO_SNAPSHOT);
}

const pb::FieldDescriptorProto* state_field(const pb::FileDescriptorSet& set,
                                            const std::string& message, const std::string& name) {
  return testing::find_field(set, message, name);
}

TEST(ProtoSchemaV13, VehicleStateIsRecordedInTheSnapshotWithItsNumbers) {
  const auto snapshot = state_snapshot();
  const struct {
    const char* message;
    const char* field;
    int number;
  } fields[] = {
      {"Envelope", "state", 20},
      {"VehicleState", "updated_at_us", 1},
      {"VehicleState", "online", 2},
      {"VehicleState", "mode", 3},
      {"VehicleState", "locks", 4},
      {"VehicleState", "speed_limit_dkmh", 5},
      {"VehicleState", "assist", 6},
      {"VehicleState", "assist_name", 7},
      {"VehicleState", "soc_pct", 8},
      {"VehicleState", "range_m", 9},
      {"VehicleState", "odo_m", 10},
      {"VehicleState", "faults", 11},
      {"VehicleState", "active_alarms", 12},
      {"VehicleState", "position", 13},
      {"VehicleState", "bus_state", 14},
      {"VehicleLock", "state", 3},
      {"VehicleFault", "code", 3},
  };
  for (const auto& f : fields) {
    const auto* d = state_field(snapshot, f.message, f.field);
    ASSERT_NE(d, nullptr) << f.message << "." << f.field
                          << " is not in the snapshot: update it (docs/uplink.md)";
    EXPECT_EQ(d->number(), f.number) << f.message << "." << f.field;
  }
  // A body of the oneof, not a header field.
  const auto* body = state_field(snapshot, "Envelope", "state");
  ASSERT_NE(body, nullptr);
  EXPECT_TRUE(body->has_oneof_index());
}

TEST(ProtoSchemaV13, AStateEnvelopeRoundTripsWithAbsentValuesAbsent) {
  v1::Envelope env;
  env.set_vehicle_id("bike-1");
  auto* s = env.mutable_state();
  s->set_online(true);
  s->set_mode(v1::VEHICLE_MODE_PARKED);
  s->set_soc_pct(0);  // measured 0 %, not "unknown"
  v1::Envelope back;
  ASSERT_TRUE(back.ParseFromString(env.SerializeAsString()));
  ASSERT_TRUE(back.has_state());
  EXPECT_TRUE(back.state().has_soc_pct());
  EXPECT_EQ(back.state().soc_pct(), 0u);
  EXPECT_FALSE(back.state().has_odo_m());
  EXPECT_FALSE(back.state().has_position());
  EXPECT_EQ(back.state().mode(), v1::VEHICLE_MODE_PARKED);
}

}  // namespace
}  // namespace fleetgw::uplink
