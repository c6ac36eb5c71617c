// Schema v1.1 (issue 15): the additions are recorded in the committed descriptor snapshot (so a
// later removal or renumbering is caught by ProtoCompat), every current on the wire has one sign
// unless deprecated, and the envelope header carries the store id byte-identically in both
// serialisation paths.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/envelope_writer.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::uplink {
namespace {

namespace pb = google::protobuf;

pb::FileDescriptorSet committed_snapshot() {
  return testing::load_snapshot(FLEETGW_PROTO_SNAPSHOT);
}

const pb::FieldDescriptorProto* find_field(const pb::FileDescriptorSet& set,
                                           const std::string& message, const std::string& name) {
  return testing::find_field(set, message, name);
}

int enum_number(const pb::FileDescriptorSet& set, const std::string& e, const std::string& value) {
  for (const auto& f : set.file()) {
    for (const auto& en : f.enum_type()) {
      if (en.name() != e) continue;
      for (const auto& v : en.value()) {
        if (v.name() == value) return v.number();
      }
    }
  }
  return -1;
}

TEST(ProtoSchemaV11, AdditionsAreRecordedInTheSnapshotWithTheirNumbers) {
  const auto snapshot = committed_snapshot();
  const struct {
    const char* message;
    const char* field;
    int number;
  } fields[] = {
      {"Envelope", "store_id", 5},
      {"Status", "last_will", 14},
      {"Status", "connected_at_us", 15},
      {"LockEvent", "previous_state_name", 7},
      {"LockEvent", "state_name", 8},
      {"LockEvent", "node", 9},
      {"PackStatistics", "discharge_current_ma", 14},
      // v1.4, MQTT 5: why the broker refuses publishes (docs/uplink.md "MQTT 5").
      {"Status", "publish_refusals", 16},
      {"Status", "last_publish_refusal", 17},
      {"Status", "last_publish_refusal_code", 18},
      {"Status", "last_publish_refusal_at_us", 19},
  };
  for (const auto& f : fields) {
    const auto* d = find_field(snapshot, f.message, f.field);
    ASSERT_NE(d, nullptr) << f.message << "." << f.field
                          << " is not in the snapshot: update it (docs/uplink.md)";
    EXPECT_EQ(d->number(), f.number) << f.message << "." << f.field;
  }
  EXPECT_EQ(enum_number(snapshot, "LockState", "LOCK_STATE_UNLOCKING"), 4);
  EXPECT_EQ(enum_number(snapshot, "LockState", "LOCK_STATE_LOCKING"), 5);
  // Envelope numbers 5..9 are the header's; 10 and up the body oneof.
  const auto* store_id = find_field(snapshot, "Envelope", "store_id");
  ASSERT_NE(store_id, nullptr);
  EXPECT_FALSE(store_id->has_oneof_index());
}

// One sign for current on the wire: positive = discharging. A field named *current_ma is
// either TelemetrySample.current_ma (discharge positive), named discharge_*, or deprecated.
TEST(ProtoSchemaV11, EveryCurrentIsDischargePositiveOrDeprecated) {
  const auto set = testing::current_fleetgw_descriptors();
  int currents = 0;
  for (const auto& f : set.file()) {
    for (const auto& m : f.message_type()) {
      for (const auto& field : m.field()) {
        if (!field.name().ends_with("current_ma")) continue;
        ++currents;
        const bool ok = (m.name() == "TelemetrySample" && field.name() == "current_ma") ||
                        field.name().starts_with("discharge_") || field.options().deprecated();
        EXPECT_TRUE(ok) << m.name() << "." << field.name()
                        << ": a current must be discharge positive (name it discharge_*_ma)";
      }
    }
  }
  EXPECT_GE(currents, 3);
}

TEST(EnvelopeWriter, StoreIdIsInTheHeaderOfBatchesAndRecordsAlike) {
  const EnvelopeHeader header{"bike-1", 7, 1'700'000'000'000'000, "1.0.0",
                              "0b9c2c1e-6f1d-4c4e-9d7e-2f5a3b1c0d9e"};
  v1::TelemetrySample sample;
  sample.set_sampled_at_us(1);
  sample.set_speed_dkmh(253);
  TelemetryBatchWriter writer;
  ASSERT_TRUE(writer.add(sample.SerializeAsString(), 7));
  const std::string spliced = writer.take_envelope(header);

  v1::Envelope expected;
  fill_header(expected, header);
  auto* s = expected.mutable_telemetry()->add_samples();
  *s = sample;
  s->set_sequence(7);
  EXPECT_EQ(spliced, expected.SerializeAsString());
  v1::Envelope parsed;
  ASSERT_TRUE(parsed.ParseFromString(spliced));
  EXPECT_EQ(parsed.store_id(), "0b9c2c1e-6f1d-4c4e-9d7e-2f5a3b1c0d9e");

  v1::FaultEvent fault;
  fault.set_node("lock1");
  const auto* route = find_route("fault");
  ASSERT_NE(route, nullptr);
  const auto record = serialize_record(*route, header, fault.SerializeAsString());
  ASSERT_TRUE(record);
  ASSERT_TRUE(parsed.ParseFromString(*record));
  EXPECT_EQ(parsed.store_id(), header.store_id);
  EXPECT_EQ(parsed.sequence(), 7u);
}

}  // namespace
}  // namespace fleetgw::uplink
