// Zone bundles over MQTT through the real `fleetgw run` and a real mosquitto (issue 14): bundles
// signed with `fleetgw zones sign`, published retained on the fleet-wide and the vehicle's own
// zones topic; what the gateway made of each one read back with `fleetgw status --json` (the
// technician's view), from its bundle file and from its log. Then, with a real gpsd fed by
// gpsfake, a bundle replaced at run time applies at the current fix at once (the
// outside_operating_area alarm, also in the retained VehicleState), and a lock made on the bike
// in a no-parking zone is reported on .../zone. A bundle on the vehicle's own topic must be
// signed for that vehicle (`zones sign --vehicle`, issue 24). Every wait is for a condition.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/vehicle_watcher.h"
#include "tests/support/wait.h"
#include "tests/support/zone_operator.h"

namespace {

using fleetgw::testing::FakeGps;
using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::geojson_feature;
using fleetgw::testing::geojson_rect;
using fleetgw::testing::have_gpsfake;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using fleetgw::testing::VehicleWatcher;
using fleetgw::testing::wait_until;
using fleetgw::testing::ZoneOperator;
using namespace std::chrono_literals;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;

using ::fleetgw::testing::read_text_file;
// Publishes retained messages, as an operator's `mosquitto_pub -r` would.
void publish_retained(const std::string& uri, const std::string& topic,
                      const std::string& payload) {
  mqtt::async_client client(uri, "zones-publisher-" + std::to_string(getpid()));
  client.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
  client.publish(mqtt::make_message(topic, payload, 1, true))->wait();
  client.disconnect()->wait();
}

// `fleetgw status --json`: the document the technician's tool reads (null when no answer).
nlohmann::json status_of(const TempDir& dir, const std::filesystem::path& config) {
  const auto out = dir.path() / "status.json";
  const auto err = dir.path() / "status.err";
  std::filesystem::remove(out);
  fleetgw::testing::run_for_exit_code(
      {FLEETGW_BINARY, "status", "--config", config.string(), "--json"}, out, err);
  auto doc = nlohmann::json::parse(read_text_file(out), nullptr, false);
  return doc.is_object() ? doc : nlohmann::json();
}

// The geofence section's value at `key`, or null.
nlohmann::json geofence_field(const nlohmann::json& status, const std::string& key) {
  if (!status.is_object() || !status.contains("geofence")) return nullptr;
  return status["geofence"].value(key, nlohmann::json());
}

// The zones' gateway: status socket on (`fleetgw status` reads it), the uplink quick to
// reconnect and to publish its state, gpsd, the bundle file in `dir`, the operator's key.
GatewayConfig zone_gateway(const TempDir& dir, const std::string& vehicle,
                           const std::string& broker_uri, std::uint16_t gpsd_port,
                           const std::string& key_line, const std::string& scenario) {
  GatewayConfig c(vehicle, dir / "fleetgw.db");
  c.sim(scenario, 1).set_string("status", "socket", (dir / "status.sock").string());
  c.mqtt(broker_uri).set("mqtt", "reconnect_min_ms", "100").set("mqtt", "reconnect_max_ms", "500");
  c.set("mqtt", "state_interval_ms", "200").gnss(gpsd_port);
  return c.geofence(dir / "zones.pb", key_line);
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ZonesOverMqtt, BundlesAreJudgedStoredAndKeptAndEveryRefusalIsNamed) {
  TempDir dir;
  MosquittoOptions options;
  options.persistence = true;  // the retained bundle survives the broker's outage
  MosquittoBroker broker(options);
  broker.start();
  const std::string vehicle = "zone-mqtt-1";
  ZoneOperator ops(dir, FLEETGW_BINARY);
  const auto area = [](int version) {
    return geojson_feature("city-" + std::to_string(version), "operating_area",
                           geojson_rect(kLon0 - 0.01, kLon0 + 0.01, kLat0 - 0.01, kLat0 + 0.01));
  };
  const std::string v1 = ops.bundle(1, {area(1)});
  const std::string v2 = ops.bundle(2, {area(2)});
  const std::string v3 = ops.bundle(3, {area(3)});
  // Version 3 signed for one vehicle (`zones sign --vehicle`), from the GeoJSON the operator
  // wrote for it (zone_operator.h: <dir>/zones-3.geojson).
  const auto signed_for = [&](const std::string& for_vehicle) {
    const auto out = dir.path() / ("zones-3-" + for_vehicle + ".pb");
    fleetgw::testing::run_program(
        {FLEETGW_BINARY, "zones", "sign", (dir.path() / "zones-3.geojson").string(), "--version",
         "3", "--key", ops.key_file().string(), "--vehicle", for_vehicle, "--out", out.string()},
        dir.path() / "sign.out");
    return read_text_file(out);
  };
  const std::string v3_own = signed_for(vehicle);
  const std::string v3_other = signed_for("zone-mqtt-9");
  std::string forged = ops.bundle(4, {area(4)});
  forged[forged.size() - 10] ^= 0x01;  // inside the signature (only key id "ops" follows it)

  // gpsd is not needed here: nothing listens on its port (position unknown).
  const auto config =
      zone_gateway(dir, vehicle, broker.uri(), fleetgw::testing::free_loopback_port(),
                   ops.key_line(),
                   std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/parked.toml")
          .set("geofence", "vehicle_bundles", "true")
          .set("geofence", "max_bundle_bytes", "65536")
          .write(dir / "fleetgw.toml")
          .string();
  const auto bundle_file = dir.path() / "zones.pb";
  publish_retained(broker.uri(), "fleet/v1/zones", v2);

  auto received = [&](int n) {
    return wait_until(
        [&] { return geofence_field(status_of(dir, config), "bundles_received") == n; }, 30s,
        100ms);
  };
  {
    GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "120"});
    ASSERT_TRUE(wait_until([&] { return geofence_field(status_of(dir, config), "version") == 2; },
                           30s, 100ms))
        << gw.log();
    EXPECT_EQ(read_text_file(bundle_file), v2) << "the bundle in force is stored as received";
    const auto s = status_of(dir, config);
    EXPECT_EQ(geofence_field(s, "bundles_accepted"), 1);
    EXPECT_EQ(geofence_field(s, "topics"),
              nlohmann::json::array({"fleet/v1/zones", "fleet/v1/" + vehicle + "/zones"}));
    EXPECT_TRUE(gw.log_contains("geofence: bundle on fleet/v1/zones accepted")) << gw.log();
    EXPECT_EQ(gw.stop(), 0) << gw.log();
  }

  // The broker down: the stored bundle is in force from the start.
  broker.stop();
  {
    GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "120"});
    ASSERT_TRUE(wait_until([&] { return geofence_field(status_of(dir, config), "version") == 2; },
                           30s, 100ms))
        << gw.log();
    EXPECT_TRUE(gw.log_contains("geofence: version 2 in force")) << gw.log();
    EXPECT_EQ(status_of(dir, config)["broker"]["connected"], false);
    EXPECT_EQ(geofence_field(status_of(dir, config), "bundles_received"), 0);
    EXPECT_EQ(gw.stop(), 0) << gw.log();
  }

  // Back online: the retained version 2 comes again (in force already: no refusal), then an
  // older version, a forged one, garbage and an oversized payload -- each refused and named,
  // version 2 staying in force and the service running.
  broker.start();
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "180"});
  ASSERT_TRUE(received(1)) << gw.log();
  auto s = status_of(dir, config);
  EXPECT_EQ(geofence_field(s, "version"), 2);
  EXPECT_EQ(geofence_field(s, "bundles_refused"), 0);

  struct Case {
    std::string payload;
    std::string reason;
  };
  const std::vector<Case> cases = {
      {v1, "not_newer"},
      {forged, "signature_invalid"},
      {"\x0a\x05garbage and more", "malformed"},
      {std::string(100'000, 'z'), "too_large"},
  };
  int n = 1;
  for (const auto& c : cases) {
    publish_retained(broker.uri(), "fleet/v1/zones", c.payload);
    ASSERT_TRUE(received(++n)) << c.reason << gw.log();
    s = status_of(dir, config);
    EXPECT_EQ(geofence_field(s, "last_refusal_reason"), c.reason) << s.dump(2);
    EXPECT_EQ(geofence_field(s, "last_refusal_topic"), "fleet/v1/zones");
    EXPECT_EQ(geofence_field(s, "version"), 2) << c.reason;
    EXPECT_EQ(geofence_field(s, "bundles_refused"), n - 1);
    EXPECT_TRUE(gw.log_contains("(" + c.reason + ")")) << gw.log();
    EXPECT_EQ(read_text_file(bundle_file), v2) << c.reason;
  }
  EXPECT_TRUE(gw.log_contains("payload of 100000 bytes exceeds 65536")) << gw.log();
  EXPECT_TRUE(gw.log_contains("version 2 stays in force")) << gw.log();
  // The same refusal again (a retained redelivery): counted, logged once.
  publish_retained(broker.uri(), "fleet/v1/zones", std::string(100'000, 'z'));
  ASSERT_TRUE(received(++n)) << gw.log();
  EXPECT_EQ(count_of(gw.log(), "(too_large)"), 1u) << gw.log();
  // The human rendering names it too.
  const auto text_out = dir.path() / "status.txt";
  fleetgw::testing::run_for_exit_code({FLEETGW_BINARY, "status", "--config", config}, text_out);
  const std::string text = read_text_file(text_out);
  EXPECT_NE(text.find("geofence version 2 in force: 1 zones"), std::string::npos) << text;
  EXPECT_NE(text.find("last refused on fleet/v1/zones"), std::string::npos) << text;

  // Replayed on this vehicle's own topic, a newer bundle signed for another vehicle, and a
  // fleet-wide one (it names no vehicle): each refused as wrong_vehicle, version 2 staying.
  const std::string own_topic = "fleet/v1/" + vehicle + "/zones";
  const std::vector<std::pair<std::string, std::string>> replays = {
      {v3_other, "signed for vehicle 'zone-mqtt-9', received on the vehicle's own topic of '" +
                     vehicle + "'"},
      {v3, "the bundle names no vehicle"},
  };
  for (const auto& [payload, detail] : replays) {
    publish_retained(broker.uri(), own_topic, payload);
    ASSERT_TRUE(received(++n)) << detail << gw.log();
    s = status_of(dir, config);
    EXPECT_EQ(geofence_field(s, "last_refusal_reason"), "wrong_vehicle") << s.dump(2);
    EXPECT_EQ(geofence_field(s, "last_refusal_topic"), own_topic);
    EXPECT_EQ(geofence_field(s, "version"), 2);
    EXPECT_TRUE(gw.log_contains(detail)) << gw.log();
    EXPECT_EQ(read_text_file(bundle_file), v2);
  }

  // Still serving: a newer bundle signed for this vehicle, on its own topic, is accepted and
  // stored.
  ASSERT_TRUE(gw.running()) << gw.log();
  publish_retained(broker.uri(), own_topic, v3_own);
  ASSERT_TRUE(wait_until([&] { return geofence_field(status_of(dir, config), "version") == 3; },
                         30s, 100ms))
      << gw.log();
  EXPECT_EQ(read_text_file(bundle_file), v3_own);
  EXPECT_TRUE(gw.log_contains("for vehicle '" + vehicle + "'")) << gw.log();
  EXPECT_EQ(gw.stop(), 0) << gw.log();
}

TEST(ZonesOverMqtt, AReplacedBundleAppliesAtOnceAndALockOnTheBikeInANoParkingZoneIsReported) {
  if (!have_gpsfake()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  MosquittoBroker broker;
  broker.start();
  const std::string vehicle = "zone-mqtt-2";
  ZoneOperator ops(dir, FLEETGW_BINARY);
  // The bike stands still at (kLat0, kLon0) with its frame lock (lock2) open; the rider locks it
  // with the key 60 s in.
  const auto scenario = dir.path() / "stand.toml";
  std::ofstream(scenario) << "[scenario]\nname = \"stand\"\ndescription = \"stand, lock\"\n"
                          << "duration_s = 300\n[bike]\nlocks_locked = true\n"
                          << "[[ride]]\nduration_s = 300\nspeed_kmh = 0\n"
                          << "[[event]]\nat_s = 1\naction = \"unlock\"\nnode = \"lock2\"\n"
                          << "[[event]]\nat_s = 60\naction = \"lock\"\nnode = \"lock2\"\n";
  const std::uint16_t gpsd_port = fleetgw::testing::free_loopback_port();
  const auto config =
      zone_gateway(dir, vehicle, broker.uri(), gpsd_port, ops.key_line(), scenario.string())
          .set("geofence", "min_dwell_ms", "60000")
          .write(dir / "fleetgw.toml")
          .string();
  VehicleWatcher watch(broker.uri(), vehicle);
  // gpsd with the bike standing at (kLat0, kLon0), the route played in a loop.
  FakeGps gps(
      dir, gpsd_port,
      fleetgw::testing::nmea_route(std::vector<fleetgw::testing::RoutePoint>(60, {kLat0, kLon0})),
      FakeGps::Options{});
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "240"});
  ASSERT_TRUE(wait_until(
      [&] {
        const auto s = status_of(dir, config);
        return s.is_object() && s.contains("gnss") && s["gnss"].value("fix", false);
      },
      30s, 200ms))
      << gw.log();
  // The dwell is a minute: only the evaluation at a bundle's arrival can decide in time.
  // Version 1: the bike inside its operating area, entered at once.
  publish_retained(broker.uri(), "fleet/v1/zones",
                   ops.bundle(1, {geojson_feature("city", "operating_area",
                                                  geojson_rect(kLon0 - 0.01, kLon0 + 0.01,
                                                               kLat0 - 0.01, kLat0 + 0.01))}));
  ASSERT_TRUE(
      wait_until([&] { return watch.has_zone("city", fleetgw::v1::ZONE_TRANSITION_ENTER); }, 15s))
      << gw.log();

  // Version 2 moves the area 5 km east and puts a no-parking zone where the bike stands.
  publish_retained(
      broker.uri(), "fleet/v1/zones",
      ops.bundle(
          2, {geojson_feature("city", "operating_area",
                              geojson_rect(kLon0 + 0.07, kLon0 + 0.09, kLat0 - 0.01, kLat0 + 0.01)),
              geojson_feature(
                  "station", "no_parking",
                  geojson_rect(kLon0 - 0.001, kLon0 + 0.001, kLat0 - 0.001, kLat0 + 0.001))}));
  using fleetgw::v1::ALARM_KIND_OUTSIDE_OPERATING_AREA;
  ASSERT_TRUE(wait_until(
      [&] {
        return watch.has_alarm(ALARM_KIND_OUTSIDE_OPERATING_AREA,
                               fleetgw::v1::ALARM_TRANSITION_RAISED);
      },
      15s))
      << gw.log();
  // The zone events are separate messages from the alarm (which goes out first, at once):
  // each is awaited, not assumed to have arrived with it.
  EXPECT_TRUE(
      wait_until([&] { return watch.has_zone("city", fleetgw::v1::ZONE_TRANSITION_EXIT); }, 15s))
      << gw.log();
  EXPECT_TRUE(wait_until(
      [&] { return watch.has_zone("station", fleetgw::v1::ZONE_TRANSITION_ENTER); }, 15s))
      << gw.log();
  // Listed in the retained last-known state while it is raised.
  EXPECT_TRUE(wait_until([&] { return watch.state_lists(ALARM_KIND_OUTSIDE_OPERATING_AREA); }, 15s))
      << gw.log();
  EXPECT_EQ(geofence_field(status_of(dir, config), "outside_operating_area"), true);

  // The rider locks the frame lock with the key, in the no-parking zone: reported.
  ASSERT_TRUE(wait_until(
      [&] { return watch.has_zone("station", fleetgw::v1::ZONE_TRANSITION_LOCKED_IN_NO_PARKING); },
      90s))
      << gw.log();
  EXPECT_FALSE(watch.has_zone("station", fleetgw::v1::ZONE_TRANSITION_LOCK_REFUSED));
  EXPECT_EQ(gw.stop(), 0) << gw.log();
}

}  // namespace
