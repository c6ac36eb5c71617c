// The simulator's route through a real gpsd (issue 14): `fleetgw run` with a simulated bike
// whose scenario carries a [[route]] writes NMEA on the pty named by [sim] nmea_pty, a real
// gpsd reads that pty like a serial GPS, and the gateway's own libgps client reads gpsd. The
// closed ride row in SQLite starts and ends at the route's ends, and its GNSS distance is
// within 3 % of the odometer's: the simulator derives the position from the same distance.
// Every wait is for a condition.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace sim_route_e2e {
namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::distance_m;
using fleetgw::testing::first_row_number;
using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::query_text;
using fleetgw::testing::RoutePoint;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

// About 2.5 km north, 2 km east, 1.4 km north: 5.9 km, a little less than the 6 km the bike
// rides, so the bike reaches the route's end and stays there (the odometer goes on).
constexpr RoutePoint kRoute[] = {
    {52.5200, 13.4050}, {52.5425, 13.4050}, {52.5425, 13.4345}, {52.5551, 13.4345}};

double route_length() {
  double m = 0;
  for (std::size_t i = 1; i < std::size(kRoute); ++i) m += distance_m(kRoute[i - 1], kRoute[i]);
  return m;
}

// Parked 100 s (gpsd comes up meanwhile), unlock, 18 minutes at 20 km/h, stand, lock.
std::string write_scenario(const TempDir& dir) {
  std::ostringstream s;
  s << R"toml([scenario]
name = "route"
description = "a route the bike follows at its own speed"
duration_s = 1300
start_utc = 2026-11-23T10:00:00Z

[bike]
seed = 11
soc_pct = 90
odo_km = 1200.0
assist = "eco"
locks_locked = true

[[ride]]
duration_s = 100
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
at_s = 1200
action = "lock"
node = "lock2"
)toml";
  for (const RoutePoint& p : kRoute) {
    s << "\n[[route]]\nlat_deg = " << p.lat_deg << "\nlon_deg = " << p.lon_deg << "\n";
  }
  const std::string path = (dir.path() / "route.toml").string();
  std::ofstream(path) << s.str();
  return path;
}

std::filesystem::path write_config(const TempDir& dir, std::uint16_t gpsd_port) {
  GatewayConfig c("route-bike", dir / "fleetgw.db");
  c.sim(write_scenario(dir), 20).set("sim", "start_now", "false");
  c.set_string("sim", "nmea_pty", (dir / "sim-gps").string());
  c.set("storage", "flush_ms", "100").gnss(gpsd_port).set("gnss", "max_age_ms", "3000");
  return c.write(dir / "fleetgw.toml");
}

TEST(SimRouteEndToEnd, TheSimulatedBikesRouteReachesTheRideThroughARealGpsd) {
  if (!fleetgw::testing::have_gpsfake()) {
    GTEST_SKIP() << "gpsd not installed (scripts/install-deps.sh)";
  }
  TempDir dir;
  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const auto db = dir.path() / "fleetgw.db";
  const auto pty = dir.path() / "sim-gps";
  const auto ride = [&db](const std::string& column) {
    return first_row_number(db, "rides", column);
  };
  GatewayProcess gw(FLEETGW_BINARY, write_config(dir, port), {"--bus-duration", "1240"});
  ASSERT_TRUE(wait_until([&] { return std::filesystem::is_symlink(pty); }, 20s))
      << "the simulator never made its NMEA pty\n"
      << gw.log();
  // A real gpsd on the simulator's pty, as on a bike with a serial GPS: foreground, polling
  // without waiting for a client, read-only (it never reconfigures the "receiver").
  ChildProcess gpsd({"gpsd", "-N", "-n", "-b", "-S", std::to_string(port), pty.string()},
                    dir.path() / "gpsd.log");

  ASSERT_TRUE(wait_until(
      [&] { return query_text(db, "SELECT state FROM rides ORDER BY id LIMIT 1") == "closed"; },
      300s))
      << "no closed ride\n"
      << gw.log() << gpsd.log();
  // The limits only end a hung run: the simulated bike runs in lock-step, so a loaded machine
  // makes its bus time take longer than on an idle one.
  ASSERT_EQ(gw.wait_exit(120s), 0) << gw.log();

  ASSERT_EQ(query_text(db, "SELECT count(*) FROM rides"), "1") << gw.log();
  const RoutePoint start{ride("start_lat_deg"), ride("start_lon_deg")};
  const RoutePoint end{ride("end_lat_deg"), ride("end_lon_deg")};
  ASSERT_FALSE(std::isnan(start.lat_deg) || std::isnan(end.lat_deg)) << gw.log() << gpsd.log();
  EXPECT_LT(distance_m(start, kRoute[0]), 2.0) << start.lat_deg << "," << start.lon_deg;
  EXPECT_LT(distance_m(end, kRoute[std::size(kRoute) - 1]), 2.0)
      << end.lat_deg << "," << end.lon_deg;
  const double gnss_m = ride("gnss_distance_m");
  const double odo_m = ride("distance_km") * 1000.0;
  EXPECT_NEAR(gnss_m, odo_m, 0.03 * odo_m) << "GNSS distance vs the odometer";
  EXPECT_NEAR(gnss_m, route_length(), 0.03 * route_length()) << "GNSS distance vs the route";
  const std::string track = query_text(db, "SELECT track FROM rides");
  std::cout << "[sim-route] route " << route_length() << " m, gnss_distance_m " << gnss_m
            << ", odometer " << odo_m << " m, track " << track << '\n';
  // The track bends at the route's corners: at least its four waypoints ([[lon, lat], ...]).
  EXPECT_GE(std::count(track.begin(), track.end(), '['), 5) << track;
  EXPECT_FALSE(std::filesystem::exists(pty)) << "the pty's link outlives the gateway";
}

}  // namespace
}  // namespace sim_route_e2e
