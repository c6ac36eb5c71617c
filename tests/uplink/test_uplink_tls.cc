// TLS and ACL tests against a real mosquitto with a throw-away PKI: mutual TLS, host-name
// verification, untrusted CA, an expired server certificate, and the per-vehicle ACL of
// deploy/mosquitto/ (each vehicle may write only below its own topic prefix).
#include <gtest/gtest.h>

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>
#include <regex>
#include <sstream>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/expired_pki.h"
#include "tests/uplink/uplink_test_util.h"

namespace fleetgw::uplink {
namespace {

using namespace std::chrono_literals;
using testing::drive;
using testing::MosquittoBroker;
using testing::MosquittoOptions;
using testing::received_sequences;
using testing::Subscriber;
using testing::TestPki;
using testing::wall_now;

// The ACL shipped in deploy/mosquitto/, so the test checks what production uses.
std::string deployed_acl() {
  std::ifstream in(std::string(FLEETGW_SOURCE_DIR) + "/deploy/mosquitto/acl");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

class UplinkTls : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { pki_ = std::make_unique<TestPki>(); }
  static void TearDownTestSuite() { pki_.reset(); }

  MosquittoOptions tls_options(const testing::CertKey& server) {
    MosquittoOptions o;
    o.tls = true;
    o.ca_cert = pki_->ca_cert();
    o.server = server;
    o.require_client_cert = true;
    o.acl = deployed_acl();
    return o;
  }
  UplinkConfig vehicle_config(const std::string& uri, const std::string& vehicle,
                              const testing::CertKey& cert) {
    UplinkConfig c = testing::plain_config(uri, vehicle);
    c.tls = TlsConfig{pki_->ca_cert().string(), cert.cert.string(), cert.key.string(), true};
    return c;
  }
  mqtt::ssl_options backend_ssl() {
    const auto cert = pki_->issue_client("fleet-backend");
    mqtt::ssl_options ssl;
    ssl.set_trust_store(pki_->ca_cert().string());
    ssl.set_key_store(cert.cert.string());
    ssl.set_private_key(cert.key.string());
    ssl.set_enable_server_cert_auth(true);
    ssl.set_verify(true);
    return ssl;
  }

  static std::unique_ptr<TestPki> pki_;
};
std::unique_ptr<TestPki> UplinkTls::pki_;

TEST_F(UplinkTls, ConnectsWithTheRightCaAndClientCertificate) {
  ASSERT_FALSE(deployed_acl().empty());
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/#", "backend-tls", backend_ssl());
  MemoryOutbox box;
  for (int i = 0; i < 20; ++i)
    box.push(1, kind::kFault, wall_now().count(), testing::fault_payload(i));
  Uplink up(vehicle_config(broker.uri(), "bike-tls", pki_->issue_client("bike-tls")), box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 15s))
      << broker.log();
  EXPECT_TRUE(
      sub.wait_until([](auto& m) { return received_sequences(m, "bike-tls").size() >= 20; }, 5s));
  EXPECT_EQ(up.stats().connect_failures, 0u);
}

TEST_F(UplinkTls, RefusesAServerWhoseCertificateNamesAnotherHost) {
  MosquittoBroker broker(tls_options(pki_->wrong_name_server()));
  broker.start();
  MemoryOutbox box;
  box.push(1, kind::kFault, wall_now().count(), testing::fault_payload(1));
  const auto cert = pki_->issue_client("bike-name");
  {
    Uplink up(vehicle_config(broker.uri(), "bike-name", cert), box);
    up.start(wall_now());
    ASSERT_TRUE(drive(
        up,
        [&] { return up.stats().connect_failures >= 2 && !up.stats().last_connect_error.empty(); },
        15s));
    EXPECT_EQ(up.stats().connects, 0u);
    EXPECT_EQ(box.stats().depth, 1u);
    // The reason a technician can act on, not "rc -1".
    EXPECT_EQ(up.stats().last_connect_error, "TLS: host name mismatch");
    EXPECT_GE(up.stats().tls_failures, 1u);
  }
  // Control: the same broker and chain are accepted once name checking is off, so the refusal
  // above was the host name and nothing else.
  auto cfg = vehicle_config(broker.uri(), "bike-name", cert);
  cfg.tls->verify_server_name = false;
  Uplink up(cfg, box);
  up.start(wall_now());
  EXPECT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 15s))
      << broker.log();
}

TEST_F(UplinkTls, RefusesAServerFromAnUntrustedCa) {
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  MemoryOutbox box;
  auto cfg = vehicle_config(broker.uri(), "bike-ca", pki_->issue_client("bike-ca"));
  cfg.tls->ca_file = pki_->foreign_ca_cert().string();
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up,
      [&] { return up.stats().connect_failures >= 2 && !up.stats().last_connect_error.empty(); },
      15s));
  EXPECT_EQ(up.stats().connects, 0u);
  const std::string reason = up.stats().last_connect_error;
  EXPECT_EQ(reason.rfind("TLS: certificate verify failed (", 0), 0u) << reason;
  EXPECT_EQ(reason.find("host name"), std::string::npos) << reason;
  EXPECT_GE(up.stats().tls_failures, 1u);
  EXPECT_GT(up.stats().last_connect_error_us, 0);
}

// A server whose certificate expired (chain and name are right): the reason says "expired",
// in the uplink's stats (what `fleetgw status` shows) and in the log.
TEST_F(UplinkTls, NamesAnExpiredServerCertificate) {
  testing::TempDir dir("fleetgw-expired");
  const testing::ExpiredPki pki = testing::make_expired_pki(dir.path());
  auto log = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(256);
  spdlog::default_logger()->sinks().push_back(log);
  MosquittoOptions o;
  o.tls = true;
  o.ca_cert = pki.ca_cert;
  o.server = pki.server;
  o.require_client_cert = false;
  MosquittoBroker broker(o);
  broker.start();
  MemoryOutbox box;
  box.push(1, kind::kFault, wall_now().count(), testing::fault_payload(3));
  auto cfg = testing::plain_config(broker.uri(), "bike-expired");
  cfg.tls = TlsConfig{pki.ca_cert.string(), "", "", true};
  {
    Uplink up(cfg, box);
    up.start(wall_now());
    ASSERT_TRUE(drive(
        up,
        [&] { return up.stats().connect_failures >= 2 && !up.stats().last_connect_error.empty(); },
        15s));
    EXPECT_EQ(up.stats().connects, 0u);
    EXPECT_EQ(box.stats().depth, 1u);
    EXPECT_EQ(up.stats().last_connect_error,
              "TLS: certificate verify failed (certificate has expired)");
    EXPECT_GE(up.stats().tls_failures, 1u);
  }
  int expired_lines = 0;
  for (const auto& line : log->last_formatted()) {
    if (line.find("cannot connect") != std::string::npos &&
        line.find("certificate has expired") != std::string::npos) {
      ++expired_lines;
    }
  }
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), log), sinks.end());
  EXPECT_EQ(expired_lines, 1) << "logged once, with the reason";
}

TEST_F(UplinkTls, ReasonIsLoggedOncePerDistinctCauseAndClearedOnConnect) {
  auto log = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(256);
  spdlog::default_logger()->sinks().push_back(log);
  const auto count_reason_lines = [&] {
    int n = 0;
    for (const auto& line : log->last_formatted()) {
      if (line.find("cannot connect") != std::string::npos) ++n;
    }
    return n;
  };
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  MemoryOutbox box;
  box.push(1, kind::kFault, wall_now().count(), testing::fault_payload(2));
  // An untrusted CA first: every retry fails the same way.
  auto cfg = vehicle_config(broker.uri(), "bike-once", pki_->issue_client("bike-once"));
  cfg.tls->ca_file = pki_->foreign_ca_cert().string();
  {
    Uplink up(cfg, box);
    up.start(wall_now());
    ASSERT_TRUE(drive(
        up, [&] { return up.stats().connect_failures >= 5 && up.stats().tls_failures >= 3; }, 20s));
    EXPECT_EQ(count_reason_lines(), 1) << "one line per distinct reason, not per retry";
  }
  // The right CA: connected, the reason is gone.
  cfg.tls->ca_file = pki_->ca_cert().string();
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 15s))
      << broker.log();
  EXPECT_TRUE(up.stats().last_connect_error.empty());
  EXPECT_EQ(up.stats().last_connect_error_us, 0);
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), log), sinks.end());
}

TEST_F(UplinkTls, BrokerRefusesAClientWithoutCertificate) {
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  MemoryOutbox box;
  auto cfg = testing::plain_config(broker.uri(), "bike-nocert");
  cfg.tls = TlsConfig{pki_->ca_cert().string(), "", "", true};
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().connect_failures >= 2; }, 15s));
  EXPECT_EQ(up.stats().connects, 0u);
}

TEST_F(UplinkTls, AclLetsAVehicleWriteOnlyItsOwnTopics) {
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  Subscriber backend(broker.uri(), "fleet/v1/#", "backend-acl", backend_ssl());
  // A raw client holding bike-a's certificate tries to write into bike-b's topics.
  const auto cert_a = pki_->issue_client("bike-a");
  mqtt::ssl_options ssl;
  ssl.set_trust_store(pki_->ca_cert().string());
  ssl.set_key_store(cert_a.cert.string());
  ssl.set_private_key(cert_a.key.string());
  Subscriber bike_a(broker.uri(), "fleet/v1/bike-a/cmd", "bike-a", ssl);
  auto& a = bike_a.client();
  a.publish("fleet/v1/bike-b/telemetry", std::string("forged"), 1, false)->wait();
  a.publish("fleet/v1/bike-b/status", std::string("forged"), 1, true)->wait();
  a.publish("fleet/v1/bike-a/telemetry", std::string("own"), 1, false)->wait();  // sentinel
  ASSERT_TRUE(backend.wait_until(
      [](auto& m) {
        return std::any_of(m.begin(), m.end(), [](auto& r) { return r.payload == "own"; });
      },
      5s))
      << broker.log();
  for (const auto& m : backend.messages()) {
    EXPECT_NE(m.payload, "forged") << "the broker forwarded a write into " << m.topic;
  }
  // The vehicle can receive its commands (the ACL grants read on its cmd topic).
  backend.client().publish("fleet/v1/bike-a/cmd", std::string("cmd"), 1, false)->wait();
  EXPECT_TRUE(bike_a.wait_until([](auto& m) { return !m.empty(); }, 5s));
}

// Every topic of the gateway's topic table (topics.h) through the shipped ACL: a client holding
// bike-t's certificate publishes on each published topic and the backend receives it; the backend
// publishes on each subscribed topic and the vehicle receives it. The test above only covered
// telemetry, status and cmd; the shipped file then denied alarm, state and zone.
TEST_F(UplinkTls, ShippedAclGrantsEveryTopicOfTheTopicTable) {
  MosquittoBroker broker(tls_options(pki_->server()));
  broker.start();
  Subscriber backend(broker.uri(), "fleet/v1/#", "backend-table", backend_ssl());
  const auto cert = pki_->issue_client("bike-t");
  mqtt::ssl_options ssl;
  ssl.set_trust_store(pki_->ca_cert().string());
  ssl.set_key_store(cert.cert.string());
  ssl.set_private_key(cert.key.string());
  const Topics topics("fleet/v1", "bike-t");
  Subscriber bike(broker.uri(), topics.cmd, "bike-t", ssl);
  std::vector<std::string> published, subscribed;
  for (const auto& t : kTopicTable) {
    const std::string& name = topics.*t.member;
    if (t.direction == TopicDirection::kPublish) {
      published.push_back(name);
      bike.client().publish(name, "from-vehicle:" + name, 1, false)->wait();
    } else {
      subscribed.push_back(name);
      if (name != topics.cmd) bike.client().subscribe(name, 1)->wait();
    }
  }
  const auto has_all = [](const std::vector<testing::Received>& m,
                          const std::vector<std::string>& topics_wanted, const std::string& tag) {
    for (const auto& t : topics_wanted) {
      if (std::none_of(m.begin(), m.end(),
                       [&](const auto& r) { return r.topic == t && r.payload == tag + t; })) {
        return false;
      }
    }
    return true;
  };
  EXPECT_TRUE(
      backend.wait_until([&](const auto& m) { return has_all(m, published, "from-vehicle:"); }, 5s))
      << broker.log();
  for (const auto& name : published) {
    const auto m = backend.messages();
    EXPECT_TRUE(std::any_of(m.begin(), m.end(), [&](const auto& r) { return r.topic == name; }))
        << "the shipped ACL denies the vehicle's publish on " << name;
  }
  for (const auto& name : subscribed) {
    backend.client().publish(name, "from-backend:" + name, 1, false)->wait();
  }
  EXPECT_TRUE(
      bike.wait_until([&](const auto& m) { return has_all(m, subscribed, "from-backend:"); }, 5s))
      << broker.log();
  for (const auto& name : subscribed) {
    const auto m = bike.messages();
    EXPECT_TRUE(std::any_of(m.begin(), m.end(), [&](const auto& r) { return r.topic == name; }))
        << "the shipped ACL does not let the vehicle read " << name;
  }
  EXPECT_EQ(broker.log().find("Denied"), std::string::npos) << broker.log();
}

}  // namespace
}  // namespace fleetgw::uplink
