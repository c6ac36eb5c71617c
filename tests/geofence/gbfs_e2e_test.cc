// A city's GBFS geofencing_zones.json onto a simulated bike and back (issue 27), through the
// shipped binary and a real mosquitto: tests/geofence/data/ljubljana_geofencing_zones.json
// signed by `fleetgw zones sign` as published, retained on fleet/v1/zones, put in force by
// `fleetgw run` (a city e-bike: [vehicle] type_id), a real gpsd fed by gpsfake riding north
// from the railway station through the old town. At the station an unlock is refused
// (no_start_zone); then the MC is given the rules in GBFS order for the bike's type, in force
// by the gateway's clock: 12 km/h in the old town (not the cargo bikes' 6, not the 5 of the
// 2020 market whose window is over), 20 where Slovenska cesta -- listed first -- crosses it
// (UNION would keep 12), 8 in the festival, 25 after. `fleetgw zones export` then gives the
// city's document back. The fixes carry gpsd's heading (issue 27). Every wait is for a
// condition.
#include <gtest/gtest.h>

#include <mqtt/async_client.h>
#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

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
using fleetgw::testing::have_gpsfake;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::RoutePoint;
using fleetgw::testing::TempDir;
using fleetgw::testing::VehicleWatcher;
using fleetgw::testing::wait_until;
using fleetgw::testing::ZoneOperator;
using namespace std::chrono_literals;

const std::string kGbfsCity =
    std::string(FLEETGW_SOURCE_DIR) + "/tests/geofence/data/ljubljana_geofencing_zones.json";
constexpr double kGbfsLon = 14.5060;   // the file's north-south axis
constexpr double kGbfsLat0 = 46.0560;  // the railway station forecourt
constexpr double kGbfsStep = 0.00027;  // 30 m a second, north

// The limits the gateway's log says the MC confirmed, in order.
std::vector<int> gbfs_confirmed_limits(const std::string& log) {
  std::vector<int> out;
  static const std::regex re("geofence: MC speed limit ([0-9]+) km/h confirmed");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), re); it != std::sregex_iterator();
       ++it) {
    out.push_back(std::stoi((*it)[1].str()));
  }
  return out;
}

// `limits` reaches each of `stops` in order (every value in between is a ramp step).
bool reaches_in_order(const std::vector<int>& limits, const std::vector<int>& stops) {
  auto it = limits.begin();
  for (const int stop : stops) {
    it = std::find(it, limits.end(), stop);
    if (it == limits.end()) return false;
  }
  return true;
}

TEST(GbfsEndToEnd, ACitysGbfsZonesAreEnforcedByOrderTypeAndWindowAndExportedBack) {
  if (!have_gpsfake()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  MosquittoBroker broker;
  broker.start();
  const std::string vehicle = "gbfs-bike";
  VehicleWatcher sub(broker.uri(), vehicle);

  // The operator signs the city's file as published.
  ZoneOperator ops(dir, FLEETGW_BINARY);
  const auto signed_file = dir.path() / "city-5.pb";
  const auto sign_out = dir.path() / "sign.out";
  ASSERT_EQ(fleetgw::testing::run_for_exit_code(
                {FLEETGW_BINARY, "zones", "sign", kGbfsCity, "--version", "5", "--key",
                 ops.key_file().string(), "--out", signed_file.string()},
                sign_out),
            0)
      << fleetgw::testing::read_text_file(sign_out);
  EXPECT_NE(fleetgw::testing::read_text_file(sign_out).find("version 5, 8 zones"),
            std::string::npos)
      << fleetgw::testing::read_text_file(sign_out);

  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  GatewayConfig c(vehicle, dir.path() / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/parked.toml", 1);
  c.set_string("vehicle", "type_id", "city-ebike");
  c.mqtt(broker.uri())
      .set("mqtt", "reconnect_min_ms", "100")
      .set("mqtt", "reconnect_max_ms", "500");
  const auto in_force = dir.path() / "in-force.pb";
  c.gnss(port).geofence(in_force, ops.key_line()).set("geofence", "min_dwell_ms", "1000");
  c.set("geofence", "speed_ramp_ms", "1000").set("geofence", "restore_ramp_ms", "1000");
  const auto config = c.write(dir / "fleetgw.toml");
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "200"});
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("uplink: connected"); }, 20s)) << gw.log();
  {
    mqtt::async_client client(broker.uri(), "gbfs-publisher-" + std::to_string(getpid()));
    client.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client
        .publish(mqtt::make_message("fleet/v1/zones", fleetgw::testing::read_text_file(signed_file),
                                    1, true))
        ->wait();
    client.disconnect()->wait();
  }
  ASSERT_TRUE(wait_until(
      [&] { return gw.log_contains("bundle on fleet/v1/zones accepted: version 5"); }, 20s))
      << gw.log();

  // 8 s at the station, north through the old town to the service area's north, then there.
  std::vector<RoutePoint> route;
  for (int i = 0; i < 8; ++i) route.push_back({kGbfsLat0, kGbfsLon});
  for (int i = 0; i * kGbfsStep < 0.0100; ++i)
    route.push_back({kGbfsLat0 + i * kGbfsStep, kGbfsLon});
  for (int i = 0; i < 30; ++i) route.push_back({kGbfsLat0 + 0.0100, kGbfsLon});
  FakeGps gps(dir, port, fleetgw::testing::nmea_route(route), FakeGps::Options{});

  // At the station: no ride starts here.
  ASSERT_TRUE(
      wait_until([&] { return sub.has_zone("gbfs-4", fleetgw::v1::ZONE_TRANSITION_ENTER); }, 30s))
      << ::testing::PrintToString(sub.zone_log()) << gw.log();
  const auto out = dir.path() / "command.out";
  const int code = fleetgw::testing::run_for_exit_code(
      {FLEETGW_BINARY, "command", "--vehicle", vehicle, "--lock", "vehicle", "--action", "unlock",
       "--key", ops.key_file().string(), "--broker", broker.uri(), "--timeout-s", "30"},
      out);
  const std::string result = fleetgw::testing::read_text_file(out);
  EXPECT_NE(code, 0) << result;
  EXPECT_NE(result.find("no_start_zone: will not start a ride inside the no-start zone 'gbfs-4'"),
            std::string::npos)
      << result << gw.log();

  // Along the old town: 12, up to 20 (Slovenska cesta first), down to 8 (the festival), 25.
  ASSERT_TRUE(wait_until(
      [&] {
        return reaches_in_order(gbfs_confirmed_limits(gw.log()), {12, 20, 8, 25});
      },
      90s))
      << ::testing::PrintToString(gbfs_confirmed_limits(gw.log())) << gw.log();
  const auto limits = gbfs_confirmed_limits(gw.log());
  // Down the old town's ramp to 12 (never the cargo bikes' 6 nor the 2020 market's 5), then up
  // to Slovenska cesta's 20, down to the festival's 8 and never below.
  const auto floor_12 = std::find(limits.begin(), limits.end(), 12);
  ASSERT_NE(floor_12, limits.end());
  const auto up_to_20 = std::find(floor_12, limits.end(), 20);
  ASSERT_NE(up_to_20, limits.end());
  EXPECT_EQ(*std::min_element(limits.begin(), up_to_20), 12) << ::testing::PrintToString(limits);
  EXPECT_TRUE(std::is_sorted(floor_12, up_to_20 + 1)) << ::testing::PrintToString(limits);
  EXPECT_EQ(*std::min_element(limits.begin(), limits.end()), 8) << ::testing::PrintToString(limits);
  // The expired market never entered; the rules zones are reported as such; the fixes carry
  // gpsd's heading (the route's RMC sentences: course 0.0, due north, at 10.8 knots).
  int with_heading = 0;
  for (const auto& z : sub.zones()) {
    if (z.message.position().has_heading_ddeg()) {
      ++with_heading;
      EXPECT_EQ(z.message.position().heading_ddeg(), 0u) << z.message.zone_id();
    }
    EXPECT_NE(z.message.zone_id(), "gbfs-1") << "the 2020 market is out of its window";
    EXPECT_EQ(z.message.kind(), fleetgw::v1::ZONE_KIND_RULES) << z.message.zone_id();
    EXPECT_EQ(z.message.bundle_version(), 5u);
  }
  EXPECT_GT(with_heading, 0) << "no zone event's fix carried a heading";
  EXPECT_TRUE(sub.has_zone("gbfs-3", fleetgw::v1::ZONE_TRANSITION_ENTER))
      << ::testing::PrintToString(sub.zone_log());
  EXPECT_EQ(gw.stop(), 0) << gw.log();

  // Back as GBFS from the bundle in force: the city's document (last_updated is the signing).
  const auto exported = dir.path() / "exported.json";
  const auto export_out = dir.path() / "export.out";
  ASSERT_EQ(fleetgw::testing::run_for_exit_code(
                {FLEETGW_BINARY, "zones", "export", "--config", config.string(), "--ttl", "60",
                 "--out", exported.string()},
                export_out),
            0)
      << fleetgw::testing::read_text_file(export_out);
  auto back = nlohmann::json::parse(fleetgw::testing::read_text_file(exported));
  auto original = nlohmann::json::parse(fleetgw::testing::read_text_file(kGbfsCity));
  EXPECT_TRUE(back["last_updated"].is_string());
  back.erase("last_updated");
  original.erase("last_updated");
  EXPECT_EQ(back, original) << back.dump(1);
}

}  // namespace
