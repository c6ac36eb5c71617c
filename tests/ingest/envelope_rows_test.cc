// Unit tests of the ingest's pure half (backend/ingest/envelope_rows.h): topics and Envelopes
// to rows, the sequence ranges they account for, and every hostile input rejected with a reason
// (never a crash, never a database error).
#include "backend/ingest/envelope_rows.h"

#include <google/protobuf/stubs/logging.h>
#include <gtest/gtest.h>

#include <limits>
#include <optional>
#include <random>
#include <string>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "proto/record_kinds.h"

namespace {

using fleetgw::ingest::decode_message;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::Reject;
using fleetgw::ingest::SequenceRange;
using fleetgw::ingest::table_of;
using fleetgw::ingest::TableSpec;
using fleetgw::ingest::to_ranges;
namespace records = fleetgw::records;
namespace v1 = fleetgw::v1;

v1::Envelope envelope(std::uint64_t seq) {
  v1::Envelope e;
  e.set_vehicle_id("bike-1");
  e.set_store_id("store-a");
  e.set_sequence(seq);
  e.set_created_at_us(1'700'000'000'000'000);
  e.set_gateway_fw_version("1.0");
  return e;
}

Decoded decoded(std::string_view topic, const v1::Envelope& e) {
  auto r = decode_message("fleet/v1", topic, e.SerializeAsString());
  if (auto* rej = std::get_if<Reject>(&r)) {
    ADD_FAILURE() << rej->code << ": " << rej->detail;
    return {};
  }
  return std::get<Decoded>(r);
}

std::string reject_code(std::string_view topic, std::string_view payload) {
  auto r = decode_message("fleet/v1", topic, payload);
  const auto* rej = std::get_if<Reject>(&r);
  return rej ? rej->code : "accepted";
}

// The column value of row 0 named `column` ("" for NULL).
std::string value(const Decoded& d, std::string_view column, std::size_t row = 0) {
  const auto& set = d.rows.at(0);
  std::string cols(set.table->columns);
  int index = 0;
  std::size_t pos = 0;
  while (true) {
    const std::size_t end = cols.find(", ", pos);
    if (cols.substr(pos, end - pos) == column) break;
    if (end == std::string::npos) {
      ADD_FAILURE() << "no column " << column;
      return {};
    }
    pos = end + 2;
    ++index;
  }
  const auto v = set.values().at(row * set.table->column_count + index);
  return v ? *v : "";
}

// The ingest's table of each record kind is the record-kind table's (proto/record_kinds.h).
TEST(IngestRows, EveryRecordKindGoesToTheTableTheRecordKindTableNames) {
  for (const auto& spec : records::kRecordKinds) {
    const TableSpec* t = table_of(spec.envelope_field);
    ASSERT_NE(t, nullptr) << spec.stored_name;
    EXPECT_EQ(t->table, spec.ingest_table) << spec.stored_name;
  }
  EXPECT_EQ(table_of(static_cast<int>(v1::Envelope::kState))->table, "vehicle_state");
  EXPECT_EQ(table_of(99), nullptr);
}

TEST(IngestRows, RideBecomesOneRowWithItsKeyAndAccountsForItsSequence) {
  v1::Envelope e = envelope(42);
  e.mutable_ride()->set_ride_id("r-1");
  e.mutable_ride()->set_distance_odo_m(6100);
  e.mutable_ride()->set_energy_mwh(123456);
  const Decoded d = decoded("fleet/v1/bike-1/ride", e);
  ASSERT_EQ(d.rows.size(), 1u);
  EXPECT_EQ(d.rows[0].table->table, "rides");
  EXPECT_EQ(d.rows[0].rows(), 1u);
  EXPECT_EQ(value(d, "vehicle_id"), "bike-1");
  EXPECT_EQ(value(d, "store_id"), "store-a");
  EXPECT_EQ(value(d, "sequence"), "42");
  EXPECT_EQ(value(d, "distance_odo_m"), "6100");
  EXPECT_EQ(value(d, "soc_start_pct"), "");  // absent optional → NULL, not 0
  EXPECT_EQ(value(d, "start_lat_e7"), "");   // no position → NULL, never 0,0
  EXPECT_EQ(d.ranges, (std::vector<SequenceRange>{{42, 42}}));
  EXPECT_EQ(d.records, 1u);
}

TEST(IngestRows, TelemetryBatchIsOneRowPerSampleKeyedBySampleSequence) {
  v1::Envelope e = envelope(10);
  for (std::uint64_t s : {10, 11, 12, 14}) {
    auto* sample = e.mutable_telemetry()->add_samples();
    sample->set_sequence(s);
    sample->set_sampled_at_us(1000 + s);
    sample->set_speed_dkmh(253);
    sample->set_current_ma(-1500);
  }
  const Decoded d = decoded("fleet/v1/bike-1/telemetry", e);
  ASSERT_EQ(d.rows.size(), 1u);
  EXPECT_EQ(d.rows[0].table->table, "telemetry_samples");
  EXPECT_EQ(d.rows[0].rows(), 4u);
  EXPECT_EQ(value(d, "sequence", 3), "14");
  EXPECT_EQ(value(d, "current_ma", 0), "-1500");
  EXPECT_EQ(value(d, "motor_rpm", 0), "");
  EXPECT_EQ(d.records, 4u);
  EXPECT_EQ(d.ranges, (std::vector<SequenceRange>{{10, 12}, {14, 14}}));
}

TEST(IngestRows, EvictionReportAccountsForTheEvictedRange) {
  v1::Envelope e = envelope(900);
  e.mutable_eviction()->set_evicted_records(100);
  e.mutable_eviction()->set_first_sequence(101);
  e.mutable_eviction()->set_last_sequence(200);
  (*e.mutable_eviction()->mutable_evicted_by_kind())["telemetry"] = 100;
  const Decoded d = decoded("fleet/v1/bike-1/eviction", e);
  EXPECT_EQ(d.ranges, (std::vector<SequenceRange>{{101, 200}, {900, 900}}));
  EXPECT_EQ(value(d, "by_kind"), R"({"telemetry":100})");
}

TEST(IngestRows, StatusAndStateAreLatestValuesNotRecords) {
  v1::Envelope e = envelope(0);
  e.mutable_status()->set_state(v1::ONLINE_STATE_OFFLINE);
  e.mutable_status()->set_last_will(true);
  e.mutable_status()->add_attention("storage \"full\"");
  const Decoded d = decoded("fleet/v1/bike-1/status", e);
  EXPECT_EQ(d.rows[0].table->table, "status");
  EXPECT_TRUE(d.ranges.empty());
  EXPECT_EQ(value(d, "online"), "ONLINE_STATE_OFFLINE");
  EXPECT_EQ(value(d, "attention"), R"({"storage \"full\""})");
}

// A state's locks and faults go to jsonb as arrays of objects with their keys in name order:
// plain strings as they are, a quote or a control byte escaped (the worker writes plain entries
// itself, issue 25; the others through nlohmann::json, as before).
TEST(IngestRows, StateLocksAndFaultsAreJsonArraysWithEscapedText) {
  v1::Envelope e = envelope(0);
  v1::VehicleState* s = e.mutable_state();
  s->set_updated_at_us(5);
  v1::VehicleLock* l = s->add_locks();
  l->set_node("lock1");
  l->set_kind("seat");
  l->set_state(v1::LOCK_STATE_LOCKED);
  l->set_state_name("locked");
  v1::VehicleFault* f = s->add_faults();
  f->set_node("mc");
  f->set_name("over_temp");
  f->set_code(12);
  f->set_severity("error");
  v1::VehicleFault* g = s->add_faults();
  g->set_node("bms");
  g->set_name("undefined_bit_3");
  g->set_severity("info");
  Decoded d = decoded("fleet/v1/bike-1/state", e);
  EXPECT_EQ(
      value(d, "locks"),
      R"([{"kind":"seat","node":"lock1","state":"LOCK_STATE_LOCKED","state_name":"locked"}])");
  EXPECT_EQ(value(d, "faults"),
            R"([{"code":12,"name":"over_temp","node":"mc","severity":"error"},)"
            R"({"code":null,"name":"undefined_bit_3","node":"bms","severity":"info"}])");
  l->set_state_name("say \"hi\"\t");
  g->set_name("back\\slash");
  d = decoded("fleet/v1/bike-1/state", e);
  EXPECT_EQ(value(d, "locks"), R"([{"kind":"seat","node":"lock1","state":"LOCK_STATE_LOCKED",)"
                               R"("state_name":"say \"hi\"\t"}])");
  EXPECT_EQ(value(d, "faults"),
            R"([{"code":12,"name":"over_temp","node":"mc","severity":"error"},)"
            R"({"code":null,"name":"back\\slash","node":"bms","severity":"info"}])");
  s->clear_locks();
  s->clear_faults();
  d = decoded("fleet/v1/bike-1/state", e);
  EXPECT_EQ(value(d, "locks"), "[]");
  EXPECT_EQ(value(d, "faults"), "[]");
}

// The nodes of a device info as a JSON array (the text nlohmann::json wrote before the ingest
// wrote it directly: keys sorted; quotes, backslashes and controls escaped).
TEST(IngestRows, DeviceInfoNodesAreAJsonArrayWithEscapedText) {
  v1::Envelope e = envelope(3);
  v1::NodeInfo* n = e.mutable_info()->add_nodes();
  n->set_node("mc");
  n->set_model("M\\600 \"x\"");
  n->set_serial("S\t1");
  n->set_hw_version("h1");
  n->set_fw_version("2.0");
  e.mutable_info()->add_nodes()->set_node("iot");
  Decoded d = decoded("fleet/v1/bike-1/info", e);
  EXPECT_EQ(value(d, "nodes"),
            R"([{"fw_version":"2.0","hw_version":"h1","model":"M\\600 \"x\"","node":"mc",)"
            R"("serial":"S\t1"},{"fw_version":"","hw_version":"","model":"","node":"iot",)"
            R"("serial":""}])");
  e.mutable_info()->clear_nodes();
  d = decoded("fleet/v1/bike-1/info", e);
  EXPECT_EQ(value(d, "nodes"), "[]");
}

TEST(IngestRows, StatusKeepsThePublishRefusalFields) {
  v1::Envelope e = envelope(0);
  e.mutable_status()->set_publish_refusals(3);
  e.mutable_status()->set_last_publish_refusal("not authorized");
  e.mutable_status()->set_last_publish_refusal_code(135);
  e.mutable_status()->set_last_publish_refusal_at_us(1'700'000'000'123'456);
  const Decoded d = decoded("fleet/v1/bike-1/status", e);
  EXPECT_EQ(value(d, "publish_refusals"), "3");
  EXPECT_EQ(value(d, "last_publish_refusal"), "not authorized");
  EXPECT_EQ(value(d, "last_publish_refusal_code"), "135");
  EXPECT_EQ(value(d, "last_publish_refusal_at_us"), "1700000000123456");
}

TEST(IngestRows, OutsideOperatingAreaAlarmIsStoredByName) {
  v1::Envelope e = envelope(31);
  e.mutable_alarm()->set_kind(v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  e.mutable_alarm()->set_transition(v1::ALARM_TRANSITION_RAISED);
  const Decoded d = decoded("fleet/v1/bike-1/alarm", e);
  EXPECT_EQ(d.rows.at(0).table->table, "alarms");
  EXPECT_EQ(value(d, "kind"), "ALARM_KIND_OUTSIDE_OPERATING_AREA");
}

v1::Envelope zone_event(std::uint64_t seq) {
  v1::Envelope e = envelope(seq);
  v1::ZoneEvent* z = e.mutable_zone();
  z->set_zone_id("old-town.slow");
  z->set_zone_name("Old town");
  z->set_kind(v1::ZONE_KIND_SLOW);
  z->set_transition(v1::ZONE_TRANSITION_ENTER);
  z->set_at_us(1'700'000'000'500'000);
  z->mutable_position()->set_lat_e7(483'712'345);
  z->mutable_position()->set_lon_e7(-104'567);
  z->set_bundle_version(12);
  z->set_speed_limit_kmh(15);
  return e;
}

TEST(IngestRows, ZoneEventBecomesOneRowAndAccountsForItsSequence) {
  const Decoded d = decoded("fleet/v1/bike-1/zone", zone_event(77));
  ASSERT_EQ(d.rows.size(), 1u);
  EXPECT_EQ(d.rows[0].table->table, "zone_events");
  EXPECT_EQ(d.rows[0].rows(), 1u);
  EXPECT_EQ(d.records, 1u);
  EXPECT_EQ(d.ranges, (std::vector<SequenceRange>{{77, 77}}));
  EXPECT_EQ(value(d, "vehicle_id"), "bike-1");
  EXPECT_EQ(value(d, "store_id"), "store-a");
  EXPECT_EQ(value(d, "sequence"), "77");
  EXPECT_EQ(value(d, "zone_id"), "old-town.slow");
  EXPECT_EQ(value(d, "zone_name"), "Old town");
  EXPECT_EQ(value(d, "kind"), "ZONE_KIND_SLOW");
  EXPECT_EQ(value(d, "transition"), "ZONE_TRANSITION_ENTER");
  EXPECT_EQ(value(d, "at_us"), "1700000000500000");
  EXPECT_EQ(value(d, "lat_e7"), "483712345");
  EXPECT_EQ(value(d, "lon_e7"), "-104567");
  EXPECT_EQ(value(d, "bundle_version"), "12");
  EXPECT_EQ(value(d, "speed_limit_kmh"), "15");

  // No fix: NULL position, never 0,0.
  v1::Envelope no_fix = zone_event(78);
  no_fix.mutable_zone()->clear_position();
  const Decoded n = decoded("fleet/v1/bike-1/zone", no_fix);
  EXPECT_EQ(n.rows.at(0).values().at(10), std::nullopt);
  EXPECT_EQ(n.rows.at(0).values().at(11), std::nullopt);
}

TEST(IngestRows, MalformedZoneEventIsRejectedWithTheReason) {
  auto reject = [](const v1::Envelope& e, std::string_view topic = "fleet/v1/bike-1/zone") {
    auto r = decode_message("fleet/v1", topic, e.SerializeAsString());
    const auto* rej = std::get_if<Reject>(&r);
    return rej ? *rej : Reject{"accepted", ""};
  };
  v1::Envelope no_id = zone_event(5);
  no_id.mutable_zone()->clear_zone_id();
  EXPECT_EQ(reject(no_id).code, "bad_zone_event");
  EXPECT_NE(reject(no_id).detail.find("zone.zone_id"), std::string::npos);
  v1::Envelope no_kind = zone_event(5);
  no_kind.mutable_zone()->set_kind(v1::ZONE_KIND_UNSPECIFIED);
  EXPECT_NE(reject(no_kind).detail.find("zone.kind"), std::string::npos);
  v1::Envelope no_transition = zone_event(5);
  no_transition.mutable_zone()->set_transition(v1::ZONE_TRANSITION_UNSPECIFIED);
  EXPECT_NE(reject(no_transition).detail.find("zone.transition"), std::string::npos);
  v1::Envelope nul = zone_event(5);
  nul.mutable_zone()->set_zone_name(std::string("a\0b", 3));
  EXPECT_EQ(reject(nul).code, "nul_in_text");
  EXPECT_NE(reject(nul).detail.find("zone.zone_name"), std::string::npos);
  v1::Envelope version = zone_event(5);
  version.mutable_zone()->set_bundle_version(std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(reject(version).code, "value_out_of_range");
  EXPECT_NE(reject(version).detail.find("zone.bundle_version"), std::string::npos);
  v1::Envelope zero = zone_event(0);
  EXPECT_EQ(reject(zero).code, "record_without_sequence");
  EXPECT_EQ(reject(zone_event(5), "fleet/v1/bike-1/alarm").code, "wrong_leaf");
}

TEST(IngestRows, UnstoredCommandResultHasSequenceZeroAndNoRange) {
  v1::Envelope e = envelope(0);
  e.mutable_command_result()->set_command_id("c-1");
  e.mutable_command_result()->set_command_sha256(std::string("\x01\xff", 2));
  const Decoded d = decoded("fleet/v1/bike-1/cmd/result", e);
  EXPECT_EQ(value(d, "command_sha256"), "\\x01ff");
  EXPECT_TRUE(d.ranges.empty());
}

TEST(IngestRows, CommandOnCmdTopicIsRecorded) {
  v1::Command c;
  c.set_command_id("c-9");
  c.set_vehicle_id("bike-1");
  c.set_action(v1::COMMAND_ACTION_UNLOCK);
  c.set_lock_kind("seat");
  v1::SignedCommand s;
  s.set_command(c.SerializeAsString());
  s.set_key_id("ops");
  auto r = decode_message("fleet/v1", "fleet/v1/bike-1/cmd", s.SerializeAsString());
  ASSERT_TRUE(std::holds_alternative<Decoded>(r));
  EXPECT_EQ(value(std::get<Decoded>(r), "action"), "COMMAND_ACTION_UNLOCK");
  c.set_vehicle_id("bike-2");
  s.set_command(c.SerializeAsString());
  EXPECT_EQ(reject_code("fleet/v1/bike-1/cmd", s.SerializeAsString()), "vehicle_mismatch");
}

TEST(IngestRows, HostileInputIsRejectedWithAReason) {
  v1::Envelope ride = envelope(5);
  ride.mutable_ride()->set_ride_id("r");
  const std::string good = ride.SerializeAsString();
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", "\xff\xff\xff garbage"), "not_an_envelope");
  EXPECT_EQ(reject_code("other/bike-1/ride", good), "bad_topic");
  EXPECT_EQ(reject_code("fleet/v1/bike-1", good), "bad_topic");
  EXPECT_EQ(reject_code("fleet/v1//ride", good), "bad_topic");
  EXPECT_EQ(reject_code("fleet/v1/bike-2/ride", good), "vehicle_mismatch");
  EXPECT_EQ(reject_code("fleet/v1/bike-1/fault", good), "wrong_leaf");
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", envelope(5).SerializeAsString()), "no_body");

  v1::Envelope zero = ride;
  zero.set_sequence(0);
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", zero.SerializeAsString()),
            "record_without_sequence");
  v1::Envelope huge = ride;
  huge.set_sequence(std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", huge.SerializeAsString()), "value_out_of_range");
  v1::Envelope nul = ride;
  nul.mutable_ride()->set_ride_id(std::string("a\0b", 3));
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", nul.SerializeAsString()), "nul_in_text");
  v1::Envelope longtext = ride;
  longtext.mutable_ride()->set_partial_reason(std::string(5000, 'x'));
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", longtext.SerializeAsString()), "text_too_long");
  v1::Envelope speed = ride;
  speed.mutable_ride()->set_max_speed_dkmh(std::numeric_limits<std::uint32_t>::max());
  EXPECT_EQ(reject_code("fleet/v1/bike-1/ride", speed.SerializeAsString()), "value_out_of_range");
  v1::Envelope eviction = envelope(7);
  eviction.mutable_eviction()->set_first_sequence(10);
  eviction.mutable_eviction()->set_last_sequence(9);
  EXPECT_EQ(reject_code("fleet/v1/bike-1/eviction", eviction.SerializeAsString()),
            "bad_eviction_range");
  v1::Envelope empty = envelope(7);
  empty.mutable_telemetry();
  EXPECT_EQ(reject_code("fleet/v1/bike-1/telemetry", empty.SerializeAsString()), "empty_telemetry");
}

// Random bytes and random mutations of a valid Envelope: always a Decoded or a Reject.
TEST(IngestRows, RandomBytesNeverCrash) {
  v1::Envelope e = envelope(3);
  auto* s = e.mutable_telemetry()->add_samples();
  s->set_sequence(3);
  s->set_speed_dkmh(100);
  const std::string valid = e.SerializeAsString();
  // protobuf logs every invalid UTF-8 string it meets (the ingest routes that through a rate
  // limited log; here it would only be noise).
  const google::protobuf::LogSilencer quiet;
  std::mt19937 rng(15);
  int rejected = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string payload = valid;
    if (i % 2 == 0) {
      payload.resize(rng() % 64);
      for (char& c : payload) c = static_cast<char>(rng());
    } else {
      for (int k = 0; k < 3; ++k) payload[rng() % payload.size()] = static_cast<char>(rng());
    }
    rejected += std::holds_alternative<Reject>(
        decode_message("fleet/v1", "fleet/v1/bike-1/telemetry", payload));
  }
  EXPECT_GT(rejected, 10000);
}

TEST(IngestRows, RangesMergeSortedRunsAndDuplicates) {
  EXPECT_EQ(to_ranges({5, 3, 4, 4, 9, 10, 1}),
            (std::vector<SequenceRange>{{1, 1}, {3, 5}, {9, 10}}));
  EXPECT_TRUE(to_ranges({}).empty());
}

// Issue 24: rows cost ~1 KB per sample in memory; a batch larger than the gateway's own largest
// (10,000 samples) is refused before any row is built, whatever its size on the wire.
TEST(IngestRows, TelemetryBatchOverTheGatewaysLargestIsRejectedBeforeRows) {
  const auto batch = [](int samples) {
    v1::Envelope e = envelope(0);
    for (int i = 0; i < samples; ++i) {
      e.mutable_telemetry()->add_samples()->set_sequence(static_cast<std::uint64_t>(i) + 1);
    }
    return decode_message("fleet/v1", "fleet/v1/bike-1/telemetry", e.SerializeAsString());
  };
  const auto largest = batch(10'000);
  ASSERT_TRUE(std::holds_alternative<Decoded>(largest));
  EXPECT_EQ(std::get<Decoded>(largest).records, 10'000u);
  const auto worst = batch(240'000);
  ASSERT_TRUE(std::holds_alternative<Reject>(worst));
  EXPECT_EQ(std::get<Reject>(worst).code, "too_many_samples");
  EXPECT_NE(std::get<Reject>(worst).detail.find("240000"), std::string::npos)
      << std::get<Reject>(worst).detail;
}

}  // namespace
