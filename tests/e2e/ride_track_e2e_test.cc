// A ride's track through the real `fleetgw run` (simulated bike) and a real gpsd fed by gpsfake
// (issue 14): the closed ride row in SQLite has its start and end at the NMEA route's ends, a
// GNSS distance within 3 % of the route's length and of the odometer's distance, and
// `fleetgw db export --format geojson` of that store is a LineString that Python's json module
// reads as RFC 7946. The store is read with SQLite itself; every wait is for a condition.
//
// Timing: the route is fed (faster than the bike rides it) while the ride is open, so all of it
// is inside the ride. Its length is what the scenario's odometer covers (20 km/h for 1080 s =
// 6 km), which is what lets the test compare the odometer with the GNSS distance at all: the
// simulated MC knows nothing of the route.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace ride_track_e2e {
namespace {

using fleetgw::testing::distance_m;
using fleetgw::testing::FakeGps;
using fleetgw::testing::first_row_number;
using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::query_text;
using fleetgw::testing::RoutePoint;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;
using nlohmann::json;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;
constexpr double kEarthRadiusM = 6'371'008.8;  // as gateway/gnss/position.cc
constexpr double kRad = M_PI / 180.0;

// 2.5 km north, 2 km east, 1.5 km north: 6 km in 25 m steps. The bike waits a moment at each
// corner and at the end (the same fix repeated, no distance), so a fix the gateway skips (it
// takes the latest) never cuts a corner or loses the end; and for a few seconds at the start,
// as gpsfake feeds from the moment it runs, before the gateway has connected to its gpsd.
struct Route {
  std::vector<RoutePoint> points;
  double length_m = 0;
};
Route make_route() {
  Route r;
  const double m_lat = 1.0 / (kEarthRadiusM * kRad);
  const double m_lon = m_lat / std::cos(kLat0 * kRad);
  RoutePoint at{kLat0, kLon0};
  auto dwell = [&](int fixes) {
    for (int i = 0; i < fixes; ++i) r.points.push_back(at);
  };
  dwell(50);
  const std::pair<double, double> legs[] = {{2500, 0}, {0, 2000}, {1500, 0}};  // north, east m
  for (const auto& [north, east] : legs) {
    const int steps = static_cast<int>((north + east) / 25.0);
    const RoutePoint from = at;
    for (int i = 1; i <= steps; ++i) {
      const RoutePoint next{from.lat_deg + north * i / steps * m_lat,
                            from.lon_deg + east * i / steps * m_lon};
      r.length_m += distance_m(at, next);
      at = next;
      r.points.push_back(at);
    }
    dwell(6);
  }
  return r;
}

// Unlock, ride 18 minutes at 20 km/h (6 km on the odometer), stand, lock.
std::string write_scenario(const TempDir& dir) {
  const std::string path = (dir.path() / "track.toml").string();
  std::ofstream(path) << R"toml([scenario]
name = "track"
description = "unlock, 6 km at 20 km/h, lock"
duration_s = 1200
start_utc = 2026-11-23T10:00:00Z

[bike]
seed = 11
soc_pct = 90
odo_km = 1200.0
assist = "eco"
locks_locked = true

[[ride]]
duration_s = 10
speed_kmh = 0
[[ride]]
duration_s = 1080
speed_kmh = 20
[[ride]]
duration_s = 110
speed_kmh = 0

[[event]]
at_s = 3
action = "unlock"
node = "lock2"

[[event]]
at_s = 1110
action = "lock"
node = "lock2"
)toml";
  return path;
}

std::filesystem::path write_config(const TempDir& dir, std::uint16_t gpsd_port) {
  GatewayConfig c("track-bike", dir / "fleetgw.db");
  c.sim(write_scenario(dir), 20).set("storage", "flush_ms", "100").gnss(gpsd_port);
  return c.set("gnss", "max_age_ms", "3000").write(dir / "fleetgw.toml");
}

TEST(RideTrackEndToEnd, ARideAlongAnNmeaRouteHasItsTrackInTheRowAndInGeojson) {
  if (!fleetgw::testing::have_gpsfake()) {
    GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  }
  TempDir dir;
  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const auto db = dir.path() / "fleetgw.db";
  const auto ride = [&db](const std::string& column) {
    return first_row_number(db, "rides", column);
  };
  const Route route = make_route();
  ASSERT_NEAR(route.length_m, 6000.0, 5.0);  // great-circle steps along a parallel: 1 m short
  GatewayProcess gw(FLEETGW_BINARY, write_config(dir, port), {"--bus-duration", "1140"});

  // The ride is open (the bike rides 54 s of wall time at 20x): the route goes in now, once,
  // in about 26 s (two sentences per fix, one every 40 ms). The whole route is inside the ride
  // when an open ride's checkpoint (every 1.5 s of wall time) has reached the route's end.
  ASSERT_TRUE(wait_until(
      [&] { return query_text(db, "SELECT state FROM rides ORDER BY id LIMIT 1") == "open"; },
      120s))
      << gw.log();
  FakeGps gps(dir, port, fleetgw::testing::nmea_route(route.points),
              FakeGps::Options{.cycle_s = 0.04, .once = true, .slow = false});
  ASSERT_TRUE(wait_until(
      [&] {
        const RoutePoint end{ride("end_lat_deg"), ride("end_lon_deg")};
        return !std::isnan(end.lat_deg) && distance_m(end, route.points.back()) < 2.0;
      },
      180s))
      << "the ride's end never reached the route's end (ended before it?)\n"
      << gw.log() << fleetgw::testing::read_text_file(dir.path() / "gpsfake.log");
  // The limits only end a hung run: the simulated bike runs in lock-step, so a loaded machine
  // makes its 1140 s of bus time take longer than the 57 s of an idle one.
  ASSERT_EQ(gw.wait_exit(240s), 0) << gw.log();

  ASSERT_EQ(query_text(db, "SELECT count(*) FROM rides"), "1") << gw.log();
  ASSERT_EQ(query_text(db, "SELECT state FROM rides"), "closed");
  const RoutePoint start{ride("start_lat_deg"), ride("start_lon_deg")};
  const RoutePoint end{ride("end_lat_deg"), ride("end_lon_deg")};
  ASSERT_FALSE(std::isnan(start.lat_deg) || std::isnan(end.lat_deg)) << gw.log();
  EXPECT_LT(distance_m(start, route.points.front()), 2.0) << start.lat_deg << "," << start.lon_deg;
  EXPECT_LT(distance_m(end, route.points.back()), 2.0) << end.lat_deg << "," << end.lon_deg;
  const double gnss_m = ride("gnss_distance_m");
  EXPECT_NEAR(gnss_m, route.length_m, 0.03 * route.length_m) << "GNSS distance vs the route";
  const double odo_m = ride("distance_km") * 1000.0;
  EXPECT_NEAR(gnss_m, odo_m, 0.03 * odo_m) << "GNSS distance vs the odometer";
  std::cout << "[track] route " << route.length_m << " m, gnss_distance_m " << gnss_m
            << ", odometer " << odo_m << " m, track " << query_text(db, "SELECT track FROM rides")
            << '\n';

  // The track: the route's ends and corners (it is three straight legs), [lon, lat] pairs.
  const json track = json::parse(query_text(db, "SELECT track FROM rides"), nullptr, false);
  ASSERT_TRUE(track.is_array()) << query_text(db, "SELECT track FROM rides");
  EXPECT_GE(track.size(), 4u) << track.dump();
  EXPECT_LE(track.size(), 8u) << "simplified: " << track.dump();
  EXPECT_NEAR(track.front()[0].get<double>(), kLon0, 1e-6) << "longitude first";

  // `db export --format geojson` of that store, read by Python's json module.
  const auto out = dir.path() / "rides.geojson";
  ASSERT_EQ(
      fleetgw::testing::run_for_exit_code({FLEETGW_BINARY, "db", "export", "--db", db.string(),
                                           "--table", "rides", "--format", "geojson"},
                                          out, dir.path() / "export.err"),
      0)
      << fleetgw::testing::read_text_file(dir.path() / "export.err");
  const auto summary = dir.path() / "summary.json";
  ASSERT_EQ(fleetgw::testing::run_for_exit_code(
                {"python3", std::string(FLEETGW_SOURCE_DIR) + "/tests/support/check_geojson.py",
                 out.string()},
                summary, dir.path() / "check.err"),
            0)
      << fleetgw::testing::read_text_file(dir.path() / "check.err");
  const json s = json::parse(fleetgw::testing::read_text_file(summary));
  EXPECT_EQ(s["features"], 1);
  EXPECT_EQ(s["geometry_types"]["LineString"], 1);
  EXPECT_GE(s["linestring_points"][0].get<int>(), 2);
  EXPECT_EQ(s["linestring_points"][0], track.size());
}

}  // namespace
}  // namespace ride_track_e2e
