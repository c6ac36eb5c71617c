// Unit tests of the uplink's pure parts: configuration validation, topic names, back-off,
// MemoryOutbox ordering and acks, and the schema rules (units, compatibility snapshot).
#include <gtest/gtest.h>

#include <google/protobuf/descriptor.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <utility>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/backoff.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/tcp_nodelay.h"
#include "gateway/uplink/topics.h"
#include "gateway/uplink/uplink_config.h"
#include "proto/schema_reflection.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::uplink {
namespace {

namespace pb = google::protobuf;

UplinkConfig valid() {
  UplinkConfig c;
  c.broker_uri = "tcp://127.0.0.1:1883";
  c.vehicle_id = "bike-0001";
  return c;
}

std::string error_of(const UplinkConfig& c) {
  try {
    c.validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(UplinkConfig, DefaultsAreValidAndSecure) {
  const UplinkConfig c = valid();
  EXPECT_EQ(error_of(c), "");
  EXPECT_EQ(c.qos, 1);
  EXPECT_EQ(c.keep_alive, std::chrono::seconds(30));
  EXPECT_EQ(c.topic_prefix, "fleet/v1");
  EXPECT_TRUE(TlsConfig{}.verify_server_name);
}

TEST(UplinkConfig, RejectsBadValuesNamingTheField) {
  UplinkConfig c = valid();
  c.broker_uri = "http://x:1";
  EXPECT_NE(error_of(c).find("uplink.broker_uri"), std::string::npos);
  c = valid();
  c.vehicle_id = "bike/7";
  EXPECT_NE(error_of(c).find("uplink.vehicle_id"), std::string::npos);
  c = valid();
  c.vehicle_id = "";
  EXPECT_NE(error_of(c).find("uplink.vehicle_id"), std::string::npos);
  c = valid();
  c.topic_prefix = "fleet/#";
  EXPECT_NE(error_of(c).find("uplink.topic_prefix"), std::string::npos);
  c = valid();
  c.max_in_flight = 0;
  EXPECT_NE(error_of(c).find("uplink.max_in_flight"), std::string::npos);
  c = valid();
  c.qos = 2;
  EXPECT_NE(error_of(c).find("uplink.qos"), std::string::npos);
  c = valid();
  c.broker_uri = "ssl://broker:8883";
  EXPECT_NE(error_of(c).find("uplink.tls"), std::string::npos);
  c.tls = TlsConfig{"/nonexistent/ca.pem", "", "", true};
  EXPECT_NE(error_of(c).find("uplink.tls.ca_file"), std::string::npos);
  c.tls = TlsConfig{"", "/etc/hostname", "", true};
  EXPECT_NE(error_of(c).find("together"), std::string::npos);
}

TEST(UplinkConfig, RefusesPlaintextCredentialsAndNeverEchoesThePassword) {
  UplinkConfig c = valid();
  c.username = "bike";
  c.password = "s3cr3t-pw";
  const std::string err = error_of(c);
  EXPECT_NE(err.find("unencrypted"), std::string::npos);
  EXPECT_EQ(err.find("s3cr3t-pw"), std::string::npos);
  c.allow_plaintext_credentials = true;
  EXPECT_EQ(error_of(c), "");

  c = valid();
  c.broker_uri = "tcp://user:s3cr3t-pw@host:1883";
  const std::string err2 = error_of(c);
  EXPECT_NE(err2.find("user information"), std::string::npos);
  EXPECT_EQ(err2.find("s3cr3t-pw"), std::string::npos) << err2;
}

TEST(UplinkConfig, RedactUri) {
  EXPECT_EQ(redact_uri("ssl://u:p@host:8883"), "ssl://***@host:8883");
  EXPECT_EQ(redact_uri("tcp://host:1883"), "tcp://host:1883");
  EXPECT_EQ(redact_uri("tcp://a@b@host:1"), "tcp://***@host:1");
}

TEST(TcpNodelay, BrokerPortFromEveryUriForm) {
  EXPECT_EQ(broker_port("tcp://127.0.0.1:18830"), 18830);
  EXPECT_EQ(broker_port("ssl://broker.example.com"), 8883);
  EXPECT_EQ(broker_port("mqtts://broker.example.com:9443/"), 9443);
  EXPECT_EQ(broker_port("mqtt://h"), 1883);
  EXPECT_EQ(broker_port("tcp://h"), 1883);
  EXPECT_EQ(broker_port("wss://h/mqtt"), 443);
  EXPECT_EQ(broker_port("ws://h:8080/mqtt"), 8080);
  EXPECT_EQ(broker_port("tcp://[::1]:1884"), 1884);
  EXPECT_EQ(broker_port("ssl://[2001:db8::1]"), 8883);
  EXPECT_EQ(broker_port("tcp://user:secret@h:1999"), 1999);
  EXPECT_EQ(broker_port("tcp://h:0"), std::nullopt);
  EXPECT_EQ(broker_port("tcp://h:70000"), std::nullopt);
  EXPECT_EQ(broker_port("tcp://h:12x"), std::nullopt);
  EXPECT_EQ(broker_port("localhost:1883"), std::nullopt);
  EXPECT_EQ(broker_port("unix://path"), std::nullopt);
}

namespace {
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
};

// A listening loopback socket and its port.
std::pair<std::unique_ptr<Fd>, std::uint16_t> listener() {
  auto s = std::make_unique<Fd>(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(::bind(s->fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  EXPECT_EQ(::listen(s->fd, 4), 0);
  socklen_t len = sizeof a;
  ::getsockname(s->fd, reinterpret_cast<sockaddr*>(&a), &len);
  return {std::move(s), ntohs(a.sin_port)};
}

std::unique_ptr<Fd> connect_to(std::uint16_t port) {
  auto s = std::make_unique<Fd>(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  EXPECT_EQ(::connect(s->fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  return s;
}

int nodelay(const Fd& s) {
  int flag = -1;
  socklen_t len = sizeof flag;
  ::getsockopt(s.fd, IPPROTO_TCP, TCP_NODELAY, &flag, &len);
  return flag;
}
}  // namespace

TEST(TcpNodelay, SetOnTheSocketsToTheBrokerPortOnly) {
  auto [broker, broker_port_number] = listener();
  auto [other, other_port] = listener();
  const auto to_broker = connect_to(broker_port_number);
  const auto to_other = connect_to(other_port);
  const Fd udp(::socket(AF_INET, SOCK_DGRAM, 0));
  ASSERT_EQ(nodelay(*to_broker), 0);
  EXPECT_EQ(enable_tcp_nodelay_to_port(broker_port_number), 1);
  EXPECT_EQ(nodelay(*to_broker), 1);
  EXPECT_EQ(nodelay(*to_other), 0);  // another peer is left alone
  EXPECT_EQ(nodelay(*broker), 0);    // a listener has no peer
  EXPECT_EQ(enable_tcp_nodelay_to_port(1), 0);
}

TEST(Topics, NamesPerVehicle) {
  const Topics t("fleet/v1", "bike-7");
  EXPECT_EQ(t.telemetry, "fleet/v1/bike-7/telemetry");
  EXPECT_EQ(t.status, "fleet/v1/bike-7/status");
  EXPECT_EQ(t.cmd, "fleet/v1/bike-7/cmd");
  EXPECT_EQ(t.command_result, "fleet/v1/bike-7/cmd/result");
  EXPECT_THROW(Topics("fleet/v1/", "bike"), std::invalid_argument);
  EXPECT_THROW(Topics("fleet/v1", "bi+ke"), std::invalid_argument);
  EXPECT_THROW(Topics("fleet//v1", "bike"), std::invalid_argument);
}

TEST(Backoff, GrowsExponentiallyWithJitterAndResets) {
  using std::chrono::milliseconds;
  Backoff b(milliseconds(100), milliseconds(1000), 7);
  const std::int64_t expected_max[] = {100, 200, 400, 800, 1000, 1000, 1000};
  for (const auto hi : expected_max) {
    const auto d = b.next().count();
    EXPECT_GE(d, hi / 2);
    EXPECT_LE(d, hi);
  }
  b.reset();
  EXPECT_LE(b.next().count(), 100);
  // Jitter: two vehicles with different seeds do not retry in lock-step.
  Backoff x(milliseconds(1000), milliseconds(60000), 1),
      y(milliseconds(1000), milliseconds(60000), 2);
  int differ = 0;
  for (int i = 0; i < 8; ++i) differ += x.next() != y.next();
  EXPECT_GT(differ, 4);
  EXPECT_THROW(Backoff(milliseconds(0), milliseconds(1), 1), std::invalid_argument);
}

TEST(MemoryOutbox, PeeksByPriorityThenSequenceSkippingExcluded) {
  MemoryOutbox box;
  const auto a = box.push(5, "telemetry", 1, "aa");
  const auto b = box.push(0, "fault", 2, "bb");
  const auto c = box.push(5, "telemetry", 3, "cc");
  const auto d = box.push(0, "ride", 4, "dd");
  auto got = box.peek(10, 1000, {});
  ASSERT_EQ(got.size(), 4u);
  EXPECT_EQ(got[0].seq, b);
  EXPECT_EQ(got[1].seq, d);
  EXPECT_EQ(got[2].seq, a);
  EXPECT_EQ(got[3].seq, c);
  got = box.peek(10, 1000, {b, a});
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].seq, d);
  EXPECT_EQ(got[1].seq, c);
  EXPECT_EQ(box.peek(2, 1000, {}).size(), 2u);
  EXPECT_EQ(box.peek(10, 3, {}).size(), 1u);  // byte limit, but never zero entries
  EXPECT_EQ(box.peek(10, 0, {}).size(), 1u);
  const std::uint64_t acks[] = {b, 999};
  box.ack(acks);
  EXPECT_EQ(box.stats().depth, 3u);
  EXPECT_EQ(box.stats().oldest_created_us, 1);
  EXPECT_EQ(box.acked_records(), 1u);
}

// ---- schema rules -------------------------------------------------------------------------

void for_each_message(const pb::Descriptor* m,
                      const std::function<void(const pb::Descriptor*)>& fn) {
  fn(m);
  for (int i = 0; i < m->nested_type_count(); ++i) for_each_message(m->nested_type(i), fn);
}

TEST(ProtoSchema, NoFloatingPointAnywhere) {
  const auto set = testing::current_fleetgw_descriptors();
  ASSERT_GE(set.file_size(), 10);
  const proto::SchemaReflection schema;
  const auto* pool = &schema.pool();
  for (const auto& file : set.file()) {
    const auto* fd = pool->FindFileByName(file.name());
    ASSERT_NE(fd, nullptr);
    for (int i = 0; i < fd->message_type_count(); ++i) {
      for_each_message(fd->message_type(i), [](const pb::Descriptor* m) {
        for (int f = 0; f < m->field_count(); ++f) {
          const auto t = m->field(f)->type();
          EXPECT_TRUE(t != pb::FieldDescriptor::TYPE_FLOAT && t != pb::FieldDescriptor::TYPE_DOUBLE)
              << m->field(f)->full_name() << " is floating point; use an integer in a stated unit";
        }
      });
    }
  }
}

// The generated classes are lite; `fleetgw watch` and these tests read messages through the
// descriptor set compiled into the binary, which must describe the same wire format.
TEST(ProtoSchema, CompiledInSchemaReadsWhatTheLiteClassesWrite) {
  v1::Envelope env;
  env.set_vehicle_id("bike-9");
  env.set_sequence(42);
  env.mutable_ride()->set_ride_id("r1");
  env.mutable_ride()->set_distance_odo_m(4200);
  const proto::SchemaReflection schema;
  const auto message = schema.parse("fleetgw.v1.Envelope", env.SerializeAsString());
  ASSERT_NE(message, nullptr);
  const std::string json = proto::SchemaReflection::to_json(*message);
  EXPECT_NE(json.find(R"("vehicle_id":"bike-9")"), std::string::npos) << json;
  EXPECT_NE(json.find(R"("sequence":"42")"), std::string::npos) << json;
  EXPECT_NE(json.find(R"("ride":{"ride_id":"r1","distance_odo_m":"4200")"), std::string::npos)
      << json;
  EXPECT_EQ(schema.parse("fleetgw.v1.Envelope", std::string("\xff\xff\xff", 3)), nullptr);
  EXPECT_THROW(schema.message_type("fleetgw.v1.NoSuchMessage"), std::invalid_argument);
}

TEST(ProtoSchema, TimestampsAndDurationsCarryTheirUnit) {
  const proto::SchemaReflection schema;
  EXPECT_NE(schema.message_type("fleetgw.v1.Envelope").FindFieldByName("created_at_us"), nullptr);
  const auto set = testing::current_fleetgw_descriptors();
  for (const auto& file : set.file()) {
    for (const auto& m : file.message_type()) {
      for (const auto& f : m.field()) {
        const bool timeish = f.name().find("_at") != std::string::npos ||
                             f.name().find("seen") != std::string::npos ||
                             f.name().find("duration") != std::string::npos;
        if (!timeish) continue;
        const bool has_unit = f.name().ends_with("_us") || f.name().ends_with("_ms");
        EXPECT_TRUE(has_unit) << m.name() << "." << f.name() << " needs a _us or _ms suffix";
      }
    }
  }
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The committed snapshot must be compatible with the current schema. Update it deliberately
// (after review) with:
//   FLEETGW_UPDATE_PROTO_SNAPSHOT=1 <build>/tests/uplink/uplink_tests --gtest_filter=ProtoCompat.*
// which refuses to write an incompatible snapshot.
TEST(ProtoCompat, CurrentSchemaIsCompatibleWithTheCommittedSnapshot) {
  const auto current = testing::current_fleetgw_descriptors();
  const std::string text = read_text(FLEETGW_PROTO_SNAPSHOT);
  const bool update = std::getenv("FLEETGW_UPDATE_PROTO_SNAPSHOT") != nullptr;
  // An empty snapshot is only acceptable while creating it for the first time.
  ASSERT_TRUE(update || !text.empty()) << "missing snapshot " << FLEETGW_PROTO_SNAPSHOT;
  const auto snapshot = text.empty() ? pb::FileDescriptorSet{} : testing::from_snapshot_text(text);
  const auto problems = testing::compare(snapshot, current);
  for (const auto& p : problems) ADD_FAILURE() << "incompatible schema change: " << p;
  if (problems.empty() && update) {
    std::ofstream(FLEETGW_PROTO_SNAPSHOT, std::ios::trunc) << testing::to_snapshot_text(current);
    std::cout << "updated " << FLEETGW_PROTO_SNAPSHOT << "\n";
  } else if (problems.empty() && testing::to_snapshot_text(current) != text) {
    // Additions are fine but should be recorded, so that removing them later is caught.
    std::cout << "note: the schema has compatible additions not yet in the snapshot\n";
  }
}

// The checker itself: each breaking edit of a copy of the real schema must be caught, naming
// the field; compatible edits must pass.
class ProtoCompatChecker : public ::testing::Test {
 protected:
  pb::FileDescriptorSet before = testing::current_fleetgw_descriptors();
  pb::FileDescriptorSet after = before;

  pb::DescriptorProto& msg(const std::string& name) {
    for (auto& f : *after.mutable_file()) {
      for (auto& m : *f.mutable_message_type()) {
        if (m.name() == name) return m;
      }
    }
    throw std::runtime_error("no message " + name);
  }
  pb::FieldDescriptorProto& field(const std::string& m, const std::string& name) {
    for (auto& f : *msg(m).mutable_field()) {
      if (f.name() == name) return f;
    }
    throw std::runtime_error("no field " + name);
  }
  void remove_field(const std::string& m, const std::string& name) {
    auto* fields = msg(m).mutable_field();
    for (int i = 0; i < fields->size(); ++i) {
      if (fields->Get(i).name() == name) {
        fields->DeleteSubrange(i, 1);
        return;
      }
    }
  }
  std::string all() {
    std::string s;
    for (const auto& p : testing::compare(before, after)) s += p + "\n";
    return s;
  }
};

TEST_F(ProtoCompatChecker, IdenticalSchemaPasses) {
  EXPECT_EQ(all(), "");
}

TEST_F(ProtoCompatChecker, RemovedFieldWithoutReservedFails) {
  remove_field("RideRecord", "energy_mwh");
  EXPECT_NE(all().find("fleetgw.v1.RideRecord.energy_mwh (number 12) was removed"),
            std::string::npos)
      << all();
}

TEST_F(ProtoCompatChecker, RemovedFieldWithReservedNumberAndNamePasses) {
  remove_field("RideRecord", "energy_mwh");
  auto* r = msg("RideRecord").add_reserved_range();
  r->set_start(12);
  r->set_end(13);
  EXPECT_NE(all(), "") << "number reserved but not the name must still fail";
  msg("RideRecord").add_reserved_name("energy_mwh");
  EXPECT_EQ(all(), "");
}

TEST_F(ProtoCompatChecker, RenumberedFieldFails) {
  field("TelemetrySample", "speed_dkmh").set_number(99);
  EXPECT_NE(all().find("fleetgw.v1.TelemetrySample.speed_dkmh was renumbered from 3 to 99"),
            std::string::npos)
      << all();
}

TEST_F(ProtoCompatChecker, RetypedFieldFails) {
  field("TelemetrySample", "voltage_mv").set_type(pb::FieldDescriptorProto::TYPE_FLOAT);
  EXPECT_NE(all().find("fleetgw.v1.TelemetrySample.voltage_mv (number 6) changed type"),
            std::string::npos)
      << all();
  field("TelemetrySample", "voltage_mv").set_type(pb::FieldDescriptorProto::TYPE_UINT32);
  field("TelemetrySample", "voltage_mv").set_label(pb::FieldDescriptorProto::LABEL_REPEATED);
  EXPECT_NE(all().find("voltage_mv"), std::string::npos);
}

TEST_F(ProtoCompatChecker, NewFieldAndMessagePass) {
  auto* f = msg("RideRecord").add_field();
  f->set_name("co2_saved_g");
  f->set_number(40);
  f->set_type(pb::FieldDescriptorProto::TYPE_UINT64);
  f->set_label(pb::FieldDescriptorProto::LABEL_OPTIONAL);
  after.mutable_file(0)->add_message_type()->set_name("BrandNew");
  EXPECT_EQ(all(), "");
}

TEST_F(ProtoCompatChecker, ReusingAReservedNumberFails) {
  auto* r = msg("RideRecord").add_reserved_range();
  r->set_start(30);
  r->set_end(31);
  before = after;  // the snapshot already reserves 30
  auto* f = msg("RideRecord").add_field();
  f->set_name("something_new");
  f->set_number(30);
  f->set_type(pb::FieldDescriptorProto::TYPE_UINT32);
  f->set_label(pb::FieldDescriptorProto::LABEL_OPTIONAL);
  EXPECT_NE(all().find("reuses a reserved number"), std::string::npos) << all();
}

TEST_F(ProtoCompatChecker, RemovedEnumValueAndMessageFail) {
  for (auto& file : *after.mutable_file()) {
    for (auto& e : *file.mutable_enum_type()) {
      if (e.name() != "LockState") continue;
      auto* values = e.mutable_value();
      for (int i = 0; i < values->size(); ++i) {
        if (values->Get(i).name() == "LOCK_STATE_FAULT") values->DeleteSubrange(i, 1);
      }
    }
  }
  EXPECT_NE(all().find("fleetgw.v1.LockState.LOCK_STATE_FAULT (number 3) was removed"),
            std::string::npos)
      << all();
}

}  // namespace
}  // namespace fleetgw::uplink
