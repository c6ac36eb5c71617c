// Unit tests of envelope_writer.h: a TelemetryBatch envelope spliced around the stored sample
// bytes is byte-identical to the one the generated classes build (the path the uplink used
// before: parse each sample, set its sequence, add it to the batch, serialise), and malformed
// samples are refused; the shared MQTT connection builder keeps TLS verification on.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/connect_diagnosis.h"
#include "gateway/uplink/envelope_writer.h"
#include "gateway/uplink/mqtt_connection.h"
#include "gateway/uplink/outbox_source.h"

namespace fleetgw::uplink {
namespace {

struct Stored {
  std::string bytes;
  std::uint64_t seq;
};

// The reference: what Uplink did before the splice (generated classes only).
std::string reference_envelope(const std::vector<Stored>& samples, const EnvelopeHeader& h) {
  v1::Envelope env;
  fill_header(env, h);
  for (const auto& s : samples) {
    v1::TelemetrySample sample;
    EXPECT_TRUE(sample.ParseFromString(s.bytes));
    sample.set_sequence(s.seq);
    *env.mutable_telemetry()->add_samples() = sample;
  }
  return env.SerializeAsString();
}

v1::TelemetrySample random_sample(std::mt19937_64& rng) {
  v1::TelemetrySample s;
  auto maybe = [&] { return rng() % 3 != 0; };
  s.set_sampled_at_us(static_cast<std::int64_t>(rng() >> 1));
  if (maybe()) s.set_speed_dkmh(static_cast<std::uint32_t>(rng() % 700));
  if (maybe()) s.set_motor_rpm(static_cast<std::uint32_t>(rng() % 400));
  if (maybe()) s.set_power_w(static_cast<std::int32_t>(rng() % 2000) - 1000);
  if (maybe()) s.set_voltage_mv(static_cast<std::uint32_t>(rng() % 60'000));
  if (maybe()) s.set_current_ma(static_cast<std::int32_t>(rng() % 40'000) - 20'000);
  if (maybe()) s.set_soc_pct(static_cast<std::uint32_t>(rng() % 101));
  if (maybe()) s.set_odo_m(rng() % 10'000'000'000ULL);
  if (maybe()) s.set_motor_temp_c(static_cast<std::int32_t>(rng() % 120) - 20);
  if (maybe()) s.set_pack_temp_c(static_cast<std::int32_t>(rng() % 80) - 20);
  if (maybe()) s.set_full_mah(static_cast<std::uint32_t>(rng() % 20'000));
  return s;
}

TEST(EnvelopeWriter, SplicedTelemetryBatchIsByteIdenticalToTheGeneratedPath) {
  std::mt19937_64 rng(7);
  const EnvelopeHeader header{"bike-0042", 0, 1'700'000'000'123'456, "1.2.3",
                              "6f1c0a5e-2b7d-4e3a-9c1f-0d8e7b6a5c4d"};
  for (int round = 0; round < 200; ++round) {
    std::vector<Stored> samples;
    const int n = 1 + static_cast<int>(rng() % 40);
    std::uint64_t seq = 1 + rng() % (round % 2 ? 100 : (1ULL << 40));
    TelemetryBatchWriter writer;
    for (int i = 0; i < n; ++i, ++seq) {
      auto s = random_sample(rng);
      // Some producers may already carry a (stale) sequence; the uplink's must win.
      if (rng() % 4 == 0) s.set_sequence(rng() % 1000 + 1);
      samples.push_back({s.SerializeAsString(), seq});
      ASSERT_TRUE(writer.add(samples.back().bytes, seq));
    }
    EnvelopeHeader h = header;
    h.sequence = samples.front().seq;
    const std::string expected = reference_envelope(samples, h);
    ASSERT_EQ(writer.take_envelope(h), expected) << "round " << round;
    EXPECT_TRUE(writer.empty());
  }
}

TEST(EnvelopeWriter, EmptySampleAndSizeAccountingMatchTheGeneratedSizes) {
  TelemetryBatchWriter writer;
  const std::string empty;  // a sample with nothing measured is zero bytes on the wire
  ASSERT_TRUE(writer.add(empty, 300));
  const EnvelopeHeader h{"b", 300, 5, "", ""};
  EXPECT_EQ(writer.take_envelope(h), reference_envelope({{empty, 300}}, h));

  std::mt19937_64 rng(3);
  for (int i = 0; i < 50; ++i) {
    auto s = random_sample(rng);
    const std::string bytes = s.SerializeAsString();
    s.set_sequence(1000 + i);
    EXPECT_EQ(TelemetryBatchWriter::accounted_size(bytes, 1000 + i), s.ByteSizeLong() + 4);
  }
}

TEST(EnvelopeWriter, MalformedSampleBytesAreRefusedAndAddNothing) {
  TelemetryBatchWriter writer;
  const std::string cases[] = {
      std::string("\xff\xff\xff\xff", 4),  // unterminated tag
      std::string("\x10", 1),              // tag without its varint
      std::string("\x10\xff\xff", 3),      // unterminated varint
      std::string("\x1a\x05"
                  "ab",
                  4),                      // length beyond the end
      std::string("\x0c", 1),              // end-group without a start
      std::string("\x00\x01", 2),          // field number 0
      std::string("\x08\x01\x08\x02", 4),  // two sequences: not written by the generated code
  };
  for (const auto& bytes : cases) {
    EXPECT_FALSE(writer.add(bytes, 1)) << testing::PrintToString(bytes);
    EXPECT_FALSE(TelemetryBatchWriter::accounted_size(bytes, 1).has_value());
  }
  EXPECT_TRUE(writer.empty());
}

TEST(EnvelopeWriter, OtherKindsAreValidatedAndRoutedByKind) {
  v1::FaultEvent f;
  f.set_node("mc");
  f.set_bit(3);
  const EnvelopeHeader h{"bike-1", 9, 11, "fw", "store-1"};
  const auto* route = find_route(kind::kFault);
  ASSERT_NE(route, nullptr);
  const auto bytes = serialize_record(*route, h, f.SerializeAsString());
  ASSERT_TRUE(bytes.has_value());
  v1::Envelope env;
  ASSERT_TRUE(env.ParseFromString(*bytes));
  EXPECT_EQ(env.fault().bit(), 3u);
  EXPECT_EQ(env.sequence(), 9u);
  EXPECT_FALSE(serialize_record(*route, h, std::string("\xff\xff\xff", 3)).has_value());
  EXPECT_EQ(find_route("no-such-kind"), nullptr);
}

TEST(MqttConnection, TlsVerificationIsOnByDefaultForEveryTlsUri) {
  for (const char* uri : {"ssl://broker:8883", "mqtts://broker"}) {
    ConnectionSettings s;
    s.broker_uri = uri;
    const auto opts = make_connect_options(s);
    const auto& ssl = opts.get_ssl_options();
    EXPECT_TRUE(ssl.get_enable_server_cert_auth()) << uri;
    EXPECT_TRUE(ssl.get_verify()) << uri;
  }
  ConnectionSettings s;
  s.broker_uri = "ssl://broker:8883";
  s.tls = TlsConfig{"/ca.pem", "", "", true};
  EXPECT_EQ(make_connect_options(s).get_ssl_options().get_trust_store(), "/ca.pem");
  EXPECT_EQ(normalise_broker_uri("mqtts://h:1"), "ssl://h:1");
  EXPECT_EQ(normalise_broker_uri("mqtt://h:1"), "tcp://h:1");
  EXPECT_EQ(connack_reason(5), "not authorised");
  EXPECT_TRUE(connack_reason(0).empty());
}

TEST(ConnectDiagnosis, ProbeTargetFromUris) {
  auto t = probe_target("mqtts://broker.example:8884", std::nullopt);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->host, "broker.example");
  EXPECT_EQ(t->port, 8884);
  ASSERT_TRUE(t->tls.has_value());
  EXPECT_TRUE(t->tls->verify_server_name);
  t = probe_target("tcp://[::1]:1883", std::nullopt);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->host, "::1");
  EXPECT_FALSE(t->tls.has_value());
  EXPECT_FALSE(probe_target("ws://h:80", std::nullopt).has_value());
  EXPECT_TRUE(is_tls_failure("TLS: host name mismatch"));
  EXPECT_FALSE(is_tls_failure("connection refused"));
}

TEST(ConnectDiagnosis, NothingListeningIsConnectionRefused) {
  // Port 1 on loopback: nothing listens there on a test machine.
  const auto t = probe_target("tcp://127.0.0.1:1", std::nullopt);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(diagnose_connect(*t, std::chrono::milliseconds(2000)), "connection refused");
  const auto dns = probe_target("tcp://no-such-host.invalid:1883", std::nullopt);
  EXPECT_EQ(diagnose_connect(*dns, std::chrono::milliseconds(2000)).rfind("host not found", 0), 0u);
}

}  // namespace
}  // namespace fleetgw::uplink
