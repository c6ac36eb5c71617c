// Geofences through the real `fleetgw run` (issue 14): a slow zone signed with the operator
// tools (`fleetgw keygen`, `fleetgw zones sign`), stored where the gateway keeps its bundle, a
// simulated bike, and a real gpsd fed by gpsfake with a route into the zone and out again. The
// uplink is on but its broker is down: the zones apply offline. The gateway enters the zone, the
// simulated MC is given the limit step by step down to 15 km/h (each write confirmed from the
// bus), and on leaving it the limit goes back up to 25 km/h. Every wait is for a condition.
// The second test runs with a real mosquitto: zone events, the outside_operating_area alarm and a
// ride-ending lock refused in a no-parking zone reach the broker (decoded Envelopes) and the
// SQLite store (zone_events, alarms, command_results).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
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
using fleetgw::testing::RoutePoint;
using fleetgw::testing::TempDir;
using fleetgw::testing::VehicleWatcher;
using fleetgw::testing::wait_until;
using fleetgw::testing::ZoneOperator;
using namespace std::chrono_literals;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;
constexpr double kStepDeg = 0.000045;  // about 5 m a second, north

// The limits the gateway's log says the MC confirmed, in order.
std::vector<int> confirmed_limits(const std::string& log) {
  std::vector<int> out;
  static const std::regex re("geofence: MC speed limit ([0-9]+) km/h confirmed");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), re); it != std::sregex_iterator();
       ++it) {
    out.push_back(std::stoi((*it)[1].str()));
  }
  return out;
}

TEST(GeofenceEndToEnd, ASlowZoneIsAppliedAlongTheRampAndLiftedOfflineFromTheStoredBundle) {
  if (!have_gpsfake()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  // The operator's side: a key, the zone drawn as GeoJSON, the signed bundle.
  ZoneOperator ops(dir, FLEETGW_BINARY);
  const double lat_in = kLat0 + 20 * kStepDeg, lat_out = kLat0 + 0.02;
  const auto bundle = ops.bundle_file(
      1, {geojson_feature("old-town", "slow",
                          geojson_rect(kLon0 - 0.002, kLon0 + 0.002, lat_in, lat_out),
                          R"(, "speed_limit_kmh": 15)")});

  // The bike's side: the bundle already stored, the uplink on but its broker down (nothing
  // listens on its port): the zones must not wait for it.
  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const std::uint16_t broker_port = fleetgw::testing::free_loopback_port();
  GatewayConfig c("zone-bike", dir / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/demo.toml", 1);
  c.mqtt("tcp://127.0.0.1:" + std::to_string(broker_port)).gnss(port);
  c.geofence(bundle, ops.key_line()).set("geofence", "min_dwell_ms", "2000");
  c.set("geofence", "speed_ramp_ms", "3000").set("geofence", "restore_ramp_ms", "2000");
  const auto config = c.write(dir / "fleetgw.toml");
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "240"});
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("geofence: version 1 in force"); }, 20s))
      << gw.log();

  // North for 40 s (the zone begins 20 s in), back south for 40 s, then 30 s south of it.
  std::vector<RoutePoint> route;
  for (int i = 0; i < 40; ++i) route.push_back({kLat0 + i * kStepDeg, kLon0});
  for (int i = 40; i > 0; --i) route.push_back({kLat0 + i * kStepDeg, kLon0});
  for (int i = 0; i < 30; ++i) route.push_back({kLat0, kLon0});
  FakeGps gps(dir, port, fleetgw::testing::nmea_route(route), FakeGps::Options{});

  ASSERT_TRUE(
      wait_until([&] { return gw.log_contains("geofence: enter slow zone 'old-town'"); }, 60s))
      << gw.log();
  ASSERT_TRUE(wait_until(
      [&] {
        const auto l = confirmed_limits(gw.log());
        return !l.empty() && l.back() == 15;
      },
      30s))
      << gw.log();
  // Down the ramp: one step after the other, never below 15.
  auto limits = confirmed_limits(gw.log());
  EXPECT_GE(limits.size(), 3u);
  EXPECT_TRUE(std::is_sorted(limits.rbegin(), limits.rend())) << gw.log();
  EXPECT_LT(limits.front(), 25);

  ASSERT_TRUE(
      wait_until([&] { return gw.log_contains("geofence: exit slow zone 'old-town'"); }, 90s))
      << gw.log();
  ASSERT_TRUE(wait_until(
      [&] {
        const auto l = confirmed_limits(gw.log());
        return !l.empty() && l.back() == 25;
      },
      30s))
      << gw.log();
  limits = confirmed_limits(gw.log());
  const auto lowest = std::find(limits.begin(), limits.end(), 15);
  ASSERT_NE(lowest, limits.end());
  const auto restored = std::find(lowest, limits.end(), 25);
  ASSERT_NE(restored, limits.end());
  EXPECT_TRUE(std::is_sorted(lowest, restored + 1)) << gw.log();  // back up, step by step
  // The broker was down all along, and the uplink did try it.
  EXPECT_TRUE(gw.log_contains("uplink: cannot connect to")) << gw.log();
  EXPECT_FALSE(gw.log_contains("uplink: connected")) << gw.log();
  EXPECT_EQ(gw.stop(), 0) << gw.log();
}

// Rows of one query as "a|b|c" lines (NULL as "-"); a query that cannot run fails the test.
std::vector<std::string> query(const std::filesystem::path& db, const std::string& sql) {
  fleetgw::testing::SqliteReader reader(db);
  auto rows = reader.rows(sql);
  if (!reader.error().empty()) ADD_FAILURE() << reader.error();
  return rows;
}

TEST(GeofenceEndToEnd, ZoneEventsTheAreaAlarmAndARefusedLockReachTheBrokerAndTheStore) {
  if (!have_gpsfake()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  MosquittoBroker broker;
  broker.start();
  const std::string vehicle = "zone-bike-2";
  VehicleWatcher sub(broker.uri(), vehicle);

  // 10 m a second, north. The operating area ends 150 m north; the slow zone starts 50 m north;
  // the bike starts (and stops) in a no-parking zone that ends 20 m north.
  constexpr double kStep = 2 * kStepDeg;
  const double w = kLon0 - 0.002, e = kLon0 + 0.002;
  ZoneOperator ops(dir, FLEETGW_BINARY);
  const auto bundle = ops.bundle_file(
      3, {geojson_feature("city", "operating_area",
                          geojson_rect(w, e, kLat0 - 0.001, kLat0 + 15 * kStep)),
          geojson_feature("old-town", "slow", geojson_rect(w, e, kLat0 + 5 * kStep, kLat0 + 0.02),
                          R"(, "speed_limit_kmh": 15)"),
          geojson_feature("station", "no_parking",
                          geojson_rect(w, e, kLat0 - 0.0005, kLat0 + 2 * kStep))});

  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const auto db = dir.path() / "fleetgw.db";
  GatewayConfig c(vehicle, db);
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/parked.toml", 1);
  c.mqtt(broker.uri())
      .set("mqtt", "reconnect_min_ms", "100")
      .set("mqtt", "reconnect_max_ms", "500");
  c.gnss(port).geofence(bundle, ops.key_line()).set("geofence", "min_dwell_ms", "2000");
  c.set("geofence", "speed_ramp_ms", "3000").set("geofence", "restore_ramp_ms", "2000");
  c.set("geofence", "refuse_ride_ending_locks", "true");
  const auto config = c.write(dir / "fleetgw.toml");
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "300"});
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("geofence: version 3 in force"); }, 20s))
      << gw.log();
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("uplink: connected"); }, 20s)) << gw.log();

  // 5 s at the start, north for 25 s (out of the operating area after 15), back, then 40 s at
  // the start (gpsfake then plays the route again: the position never goes stale).
  std::vector<RoutePoint> route;
  for (int i = 0; i < 5; ++i) route.push_back({kLat0, kLon0});
  for (int i = 0; i < 25; ++i) route.push_back({kLat0 + i * kStep, kLon0});
  for (int i = 25; i > 0; --i) route.push_back({kLat0 + i * kStep, kLon0});
  for (int i = 0; i < 40; ++i) route.push_back({kLat0, kLon0});
  FakeGps gps(dir, port, fleetgw::testing::nmea_route(route), FakeGps::Options{});

  using fleetgw::v1::ZONE_TRANSITION_ENTER;
  // Back in the station: its second ENTER (the first came with the first fixes).
  ASSERT_TRUE(wait_until(
      [&] {
        const auto log = sub.zone_log();
        return std::count(log.begin(), log.end(),
                          "station " + std::to_string(ZONE_TRANSITION_ENTER)) >= 2;
      },
      150s))
      << ::testing::PrintToString(sub.zone_log()) << gw.log();
  const std::vector<std::string> expected = {"city 1", "station 1", "station 2",  "old-town 1",
                                             "city 2", "city 1",    "old-town 2", "station 1"};
  // The first two come in the same fix's step, in bundle order (city first).
  EXPECT_EQ(sub.zone_log(), expected) << gw.log();
  for (const auto& z : sub.zones()) {
    EXPECT_EQ(z.topic, "fleet/v1/" + vehicle + "/zone");
    EXPECT_EQ(z.message.bundle_version(), 3u);
    EXPECT_TRUE(z.message.has_position()) << z.message.zone_id();
    EXPECT_GT(z.message.at_us(), 0);
  }
  // Leaving the operating area raised the alarm; coming back cleared it.
  const auto alarms = sub.alarms();
  ASSERT_EQ(alarms.size(), 2u) << gw.log();
  EXPECT_EQ(alarms[0].topic, "fleet/v1/" + vehicle + "/alarm");
  EXPECT_EQ(alarms[0].message.kind(), fleetgw::v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  EXPECT_EQ(alarms[0].message.transition(), fleetgw::v1::ALARM_TRANSITION_RAISED);
  EXPECT_EQ(alarms[1].message.kind(), fleetgw::v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  EXPECT_EQ(alarms[1].message.transition(), fleetgw::v1::ALARM_TRANSITION_CLEARED);

  // A ride-ending lock in the no-parking zone: refused with its reason, and reported.
  const auto out = dir.path() / "command.out";
  const int code = fleetgw::testing::run_for_exit_code(
      {FLEETGW_BINARY, "command", "--vehicle", vehicle, "--lock", "vehicle", "--action", "lock",
       "--key", ops.key_file().string(), "--broker", broker.uri(), "--timeout-s", "30"},
      out);
  const std::string result = fleetgw::testing::read_text_file(out);
  EXPECT_NE(code, 0) << "a refused command is a failure for the operator tool";
  EXPECT_NE(result.find("\"result\":\"rejected\""), std::string::npos) << result;
  EXPECT_NE(result.find("no_parking_zone: will not end the ride inside the no-parking zone "
                        "'station'"),
            std::string::npos)
      << result << gw.log();
  ASSERT_TRUE(wait_until(
      [&] { return sub.has_zone("station", fleetgw::v1::ZONE_TRANSITION_LOCK_REFUSED); }, 20s))
      << ::testing::PrintToString(sub.zone_log()) << gw.log();
  EXPECT_EQ(gw.stop(), 0) << gw.log();

  // The same in the store (the route may have started again meanwhile: only the first pass).
  const auto rows = query(db,
                          "SELECT zone_id, kind, transition, bundle_version, lat_deg IS NOT NULL "
                          "FROM zone_events WHERE transition IN ('enter', 'exit') ORDER BY id");
  ASSERT_GE(rows.size(), expected.size()) << ::testing::PrintToString(rows);
  EXPECT_EQ(rows.front(), "city|operating_area|enter|3|1");
  EXPECT_EQ(rows[4], "city|operating_area|exit|3|1");
  EXPECT_EQ(rows[7], "station|no_parking|enter|3|1");
  EXPECT_EQ(query(db,
                  "SELECT zone_id, lat_deg IS NOT NULL FROM zone_events "
                  "WHERE transition = 'lock_refused'"),
            (std::vector<std::string>{"station|1"}));
  const auto stored_alarms = query(db, "SELECT kind, transition FROM alarms ORDER BY id");
  ASSERT_GE(stored_alarms.size(), 2u);
  EXPECT_EQ(stored_alarms[0], "outside_operating_area|raised");
  EXPECT_EQ(stored_alarms[1], "outside_operating_area|cleared");
  const auto results = query(db, "SELECT result, reason FROM command_results");
  ASSERT_EQ(results.size(), 1u);
  EXPECT_NE(results[0].find("no_parking_zone"), std::string::npos) << results[0];
}

}  // namespace
