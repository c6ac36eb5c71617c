// Issue 24, finding 5: the shipped deployment works as shipped. The real `fleetgw run` on the
// simulated bike talks MQTT 5 over mutual TLS (a client certificate whose CN is the vehicle id)
// to a real mosquitto that uses deploy/mosquitto/acl AS SHIPPED, through a ride with everything
// the product sends: the bundled theft scenario (the locked bike ridden away: an alarm), the
// retained vehicle state, a signed zone bundle on the fleet-wide zones topic (a zone event at the
// bike's GNSS fix) and a signed command (its result). A backend service with its own certificate
// must receive every record kind, the broker must deny nothing, and the gateway's retained Status
// must name no refusal. Before the fix the shipped ACL denied `alarm`, `state` and `zone`: the
// theft alarm never reached the backend.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"
#include "tests/support/zone_operator.h"

namespace {

using fleetgw::testing::CertKey;
using fleetgw::testing::FakeGps;
using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using fleetgw::testing::TestPki;
using fleetgw::testing::wait_until;
using fleetgw::testing::ZoneOperator;
using namespace std::chrono_literals;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;

std::string shipped_acl() {
  return fleetgw::testing::read_text_file(std::string(FLEETGW_SOURCE_DIR) +
                                          "/deploy/mosquitto/acl");
}

// The fleet backend: its own certificate (CN fleet-backend, which the shipped ACL lets read and
// write all of fleet/v1/#), MQTT 5; every Envelope received, by topic leaf.
class Backend {
 public:
  Backend(const std::string& uri, const std::filesystem::path& ca, const CertKey& cert,
          const std::string& vehicle)
      : client_(uri, "fleet-backend-" + std::to_string(getpid()),
                mqtt::create_options(MQTTVERSION_5)),
        base_("fleet/v1/" + vehicle + "/") {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      if (!e.ParseFromString(m->get_payload())) return;
      std::lock_guard lock(mutex_);
      const std::string& t = m->get_topic();
      if (t.rfind(base_, 0) == 0) received_[t.substr(base_.size())].push_back(std::move(e));
    });
    mqtt::ssl_options ssl;
    ssl.set_trust_store(ca.string());
    ssl.set_key_store(cert.cert.string());
    ssl.set_private_key(cert.key.string());
    ssl.set_enable_server_cert_auth(true);
    ssl.set_verify(true);
    auto opts =
        mqtt::connect_options_builder().mqtt_version(MQTTVERSION_5).clean_start(true).finalize();
    opts.set_ssl(ssl);
    client_.connect(opts)->wait();
    client_.subscribe(base_ + "#", 1)->wait();
  }
  ~Backend() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {  // a destructor never throws: the broker may be gone already
    }
  }
  void publish(const std::string& topic, const std::string& payload, bool retained) {
    client_.publish(mqtt::make_message(topic, payload, 1, retained))->wait();
  }
  std::map<std::string, std::vector<fleetgw::v1::Envelope>> received() {
    std::lock_guard lock(mutex_);
    return received_;
  }
  bool has(const std::string& leaf, bool (*pred)(const fleetgw::v1::Envelope&)) {
    std::lock_guard lock(mutex_);
    const auto it = received_.find(leaf);
    if (it == received_.end()) return false;
    for (const auto& e : it->second) {
      if (pred(e)) return true;
    }
    return false;
  }

 private:
  mqtt::async_client client_;
  std::string base_;
  std::mutex mutex_;
  std::map<std::string, std::vector<fleetgw::v1::Envelope>> received_;
};

TEST(ShippedAcl, TheRealGatewayOverMutualTlsDeliversEveryRecordKindThroughTheShippedAcl) {
  if (!fleetgw::testing::have_gpsfake()) {
    GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  }
  TempDir dir("fleetgw-shipped-acl");
  TestPki pki;
  const std::string vehicle = "acl-bike-7";
  MosquittoOptions o;
  o.tls = true;
  o.ca_cert = pki.ca_cert();
  o.server = pki.server();
  o.require_client_cert = true;
  o.acl = shipped_acl();
  ASSERT_FALSE(o.acl.empty());
  MosquittoBroker broker(o);
  broker.start();
  Backend backend(broker.uri(), pki.ca_cert(), pki.issue_client("fleet-backend"), vehicle);

  ZoneOperator ops(dir, FLEETGW_BINARY);
  const CertKey bike = pki.issue_client(vehicle);
  const std::uint16_t gpsd_port = fleetgw::testing::free_loopback_port();
  GatewayConfig c(vehicle, dir / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/theft.toml", 10);
  c.mqtt(broker.uri())
      .set_string("mqtt", "ca_file", pki.ca_cert().string())
      .set_string("mqtt", "cert_file", bike.cert.string())
      .set_string("mqtt", "key_file", bike.key.string())
      .set("mqtt", "reconnect_min_ms", "100")
      .set("mqtt", "reconnect_max_ms", "500")
      .set("mqtt", "state_interval_ms", "200")
      .set("mqtt", "telemetry_qos", "1");
  c.gnss(gpsd_port).geofence(dir / "zones.pb", ops.key_line());
  const auto config = c.write(dir / "fleetgw.toml");
  // A zone bundle, retained on the fleet-wide topic (the vehicle's `pattern read fleet/v1/zones`):
  // the bike stands inside the operating area; entered once it has a fix and the dwell passed.
  backend.publish("fleet/v1/zones",
                  ops.bundle(1, {fleetgw::testing::geojson_feature(
                                    "city", "operating_area",
                                    fleetgw::testing::geojson_rect(kLon0 - 0.01, kLon0 + 0.01,
                                                                   kLat0 - 0.01, kLat0 + 0.01))}),
                  true);

  FakeGps gps(
      dir, gpsd_port,
      fleetgw::testing::nmea_route(std::vector<fleetgw::testing::RoutePoint>(60, {kLat0, kLon0})),
      FakeGps::Options{});
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "60"});

  // The theft: ridden away locked 20 s into the scenario, 2 s of evidence; 10x bus speed.
  using fleetgw::v1::Envelope;
  ASSERT_TRUE(wait_until(
      [&] {
        return backend.has("alarm", [](const Envelope& e) {
          return e.has_alarm() &&
                 e.alarm().kind() == fleetgw::v1::ALARM_KIND_UNAUTHORISED_MOVEMENT &&
                 e.alarm().transition() == fleetgw::v1::ALARM_TRANSITION_RAISED;
        });
      },
      30s))
      << "no theft alarm at the backend\n"
      << gw.log() << broker.log();

  EXPECT_TRUE(wait_until(
      [&] {
        return backend.has("zone", [](const Envelope& e) {
          return e.has_zone() && e.zone().zone_id() == "city" &&
                 e.zone().transition() == fleetgw::v1::ZONE_TRANSITION_ENTER;
        });
      },
      20s))
      << "no zone event at the backend\n"
      << gw.log() << broker.log();

  // A signed command on the vehicle's `cmd` (read) and its result on `cmd/result` (write).
  const auto key = fleetgw::command::Ed25519PrivateKey::load_pem(ops.key_file());
  const auto now = std::chrono::duration_cast<std::chrono::microseconds>(
      std::chrono::system_clock::now().time_since_epoch());
  const auto cmd =
      fleetgw::command::make_command(vehicle, "seat", "unlock", now, now + 60s, "acl-cmd-1");
  ASSERT_TRUE(cmd.has_value());
  backend.publish("fleet/v1/" + vehicle + "/cmd", fleetgw::command::sign_command(*cmd, key, "ops"),
                  false);
  EXPECT_TRUE(wait_until(
      [&] {
        return backend.has("cmd/result", [](const Envelope& e) {
          return e.has_command_result() && e.command_result().command_id() == "acl-cmd-1";
        });
      },
      20s))
      << "no command result at the backend\n"
      << gw.log() << broker.log();

  // The retained state (a change: riding, alarm raised), telemetry, the device info and the
  // online status: every kind the ride produced arrived.
  EXPECT_TRUE(wait_until(
      [&] {
        const auto r = backend.received();
        for (const char* leaf : {"telemetry", "status", "info", "state"}) {
          if (!r.contains(leaf)) return false;
        }
        return true;
      },
      10s))
      << gw.log();
  // Nothing was denied: not by the broker (its log names every denied publish and subscription)
  // and not as the gateway saw it (the latest Status names no refused kind).
  EXPECT_EQ(broker.log().find("Denied"), std::string::npos) << broker.log();
  const auto r = backend.received();
  ASSERT_TRUE(r.contains("status"));
  const auto& last = r.at("status").back().status();
  EXPECT_EQ(last.publish_refusals(), 0u) << last.last_publish_refusal();
  EXPECT_EQ(gw.log().find("refused a publish"), std::string::npos) << gw.log();
  std::set<std::string> kinds;
  for (const auto& [leaf, envs] : r) kinds.insert(leaf);
  for (const char* leaf : {"alarm", "zone", "state", "cmd/result", "telemetry", "status", "info"}) {
    EXPECT_TRUE(kinds.contains(leaf)) << leaf << " never arrived";
  }
}

}  // namespace
