// The simulated bike's route and GNSS receiver (issue 14): [[route]] parsing and its errors,
// the walk along great-circle legs, NMEA formatting (checksums, hemispheres, rounding), and the
// pty a gpsd reads, fed from a bike that rides (position = odometer distance along the route).

#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "gateway/sim/bike.h"
#include "gateway/sim/nmea_writer.h"
#include "gateway/sim/route.h"
#include "gateway/sim/sim_gnss.h"
#include "sim_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::sim {
namespace {

using testing::seconds;

void expect_route_error(const std::string& text, std::size_t line, const std::string& key,
                        const std::string& what) {
  try {
    parse_scenario(text, "bad.toml");
    FAIL() << "accepted: " << text;
  } catch (const ScenarioError& e) {
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.key(), key) << e.what();
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST(Route, ParsesWaypointsInOrder) {
  const Scenario s = parse_scenario(
      "[[route]]\nlat_deg = 52.52\nlon_deg = 13.405\n[[route]]\nlat_deg = -33\nlon_deg = -70\n",
      "r.toml");
  ASSERT_EQ(s.route.size(), 2u);
  EXPECT_DOUBLE_EQ(s.route[0].lat_deg, 52.52);
  EXPECT_DOUBLE_EQ(s.route[1].lon_deg, -70);
}

TEST(Route, BadWaypointsNameKeyIndexAndLine) {
  const std::string ok = "[[route]]\nlat_deg = 1\nlon_deg = 1\n";
  expect_route_error(ok + "[[route]]\nlat_deg = 95\nlon_deg = 1\n", 5, "route[1].lat_deg",
                     "expected a number in -90..90, got 95");
  expect_route_error(ok + "[[route]]\nlat_deg = 5\nlon_deg = -180.5\n", 6, "route[1].lon_deg",
                     "expected a number in -180..180, got -180.5");
  expect_route_error(ok + "[[route]]\nlat_deg = 5\n", 4, "route[1].lon_deg", "missing key");
  expect_route_error(ok + "[[route]]\nlat_deg = \"N5\"\nlon_deg = 1\n", 5, "route[1].lat_deg",
                     "expected a number");
  expect_route_error(ok + "[[route]]\nlat_deg = 5\nlon_deg = 1\nalt_m = 3\n", 7, "route[1].alt_m",
                     "unknown key");
  expect_route_error(ok, 1, "route", "at least 2 waypoints, got 1");
  expect_route_error("route = [1, 2]\n", 1, "route[0]", "expected a table");
}

TEST(Route, WalksGreatCircleLegsAndStaysAtTheEnd) {
  // One degree of latitude on the meridian, then east along the equator.
  const RouteWalker w({{0, 0}, {1, 0}, {1, 1}});
  const double deg_m = kRouteEarthRadiusM * M_PI / 180;
  EXPECT_NEAR(w.length_m(), deg_m + great_circle_m({1, 0}, {1, 1}), 1e-6);
  EXPECT_DOUBLE_EQ(w.at(-5).lat_deg, 0);
  EXPECT_NEAR(w.at(deg_m / 2).lat_deg, 0.5, 1e-9);
  EXPECT_NEAR(w.at(deg_m / 2).lon_deg, 0, 1e-9);
  EXPECT_NEAR(w.course_deg(deg_m / 2), 0, 1e-9);  // north
  const GeoPoint mid = w.at(deg_m + great_circle_m({1, 0}, {1, 1}) / 2);
  EXPECT_NEAR(mid.lon_deg, 0.5, 1e-6);
  EXPECT_GT(mid.lat_deg, 1.0);  // a great circle bulges poleward of the parallel
  EXPECT_NEAR(w.course_deg(deg_m + 10), 90, 0.01);
  EXPECT_DOUBLE_EQ(w.at(w.length_m() + 1000).lon_deg, 1);
  EXPECT_DOUBLE_EQ(w.at(w.length_m() + 1000).lat_deg, 1);
  // Every point on the way is where the distance says.
  for (double d = 0; d <= deg_m; d += 7919) {
    EXPECT_NEAR(great_circle_m({0, 0}, w.at(d)), d, 1e-3) << d;
  }
}

TEST(Nmea, ChecksumIsXorBetweenDollarAndStar) {
  // The textbook GGA example.
  EXPECT_EQ(nmea_checksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), "47");
  EXPECT_EQ(nmea_sentence("A"), "$A*41\r\n");
}

TEST(Nmea, AnglesHaveHemispheresAndRoundIntoTheDegree) {
  EXPECT_EQ(nmea_angle(52.52, true), "5231.20000,N");
  EXPECT_EQ(nmea_angle(-33.5, true), "3330.00000,S");
  EXPECT_EQ(nmea_angle(13.405, false), "01324.30000,E");
  EXPECT_EQ(nmea_angle(-0.5, false), "00030.00000,W");
  EXPECT_EQ(nmea_angle(-122.25, false), "12215.00000,W");
  EXPECT_EQ(nmea_angle(0, true), "0000.00000,N");
  // 59.9999999 minutes: rounds into the next degree, not "5260.00000".
  EXPECT_EQ(nmea_angle(52 + 59.9999999 / 60, true), "5300.00000,N");
  EXPECT_EQ(nmea_angle(-(179 + 59.9999996 / 60), false), "18000.00000,W");
  EXPECT_EQ(nmea_angle(52 + 59.999994 / 60, true), "5259.99999,N");
}

TEST(Nmea, FixIsGgaThenRmcWithTimeDateAndValidChecksums) {
  NmeaFix fix;
  fix.utc = Micros(int64_t{1'795'428'001} * 1'000'000 + 250'000);  // 2026-11-23T10:00:01.25Z
  fix.position = {52.52, -13.405};
  fix.speed_kmh = 18.52;  // 10 knots
  fix.course_deg = 90;
  const std::string text = nmea_fix(fix);
  const auto eol = text.find("\r\n");
  ASSERT_NE(eol, std::string::npos);
  const std::string gga = text.substr(0, eol);
  const std::string rmc = text.substr(eol + 2, text.size() - eol - 4);
  EXPECT_EQ(gga.substr(0, gga.size() - 3),
            "$GPGGA,100001.25,5231.20000,N,01324.30000,W,1,09,0.9,35.0,M,45.0,M,,");
  EXPECT_EQ(rmc.substr(0, rmc.size() - 3),
            "$GPRMC,100001.25,A,5231.20000,N,01324.30000,W,10.0,90.0,231126,,,A");
  for (const std::string& s : {gga, rmc}) {
    const auto star = s.find('*');
    ASSERT_NE(star, std::string::npos) << s;
    EXPECT_EQ(s.substr(star + 1), nmea_checksum(s.substr(1, star - 1))) << s;
  }
}

// Reads everything the pty holds (through the symlink, as gpsd opens it).
std::string drain(int fd) {
  std::string out;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n <= 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

std::vector<GeoPoint> gga_positions(const std::string& text) {
  std::vector<GeoPoint> out;
  std::size_t at = 0;
  while ((at = text.find("$GPGGA,", at)) != std::string::npos) {
    double lat = 0, lon = 0;
    char ns = 0, ew = 0;
    if (std::sscanf(text.c_str() + at, "$GPGGA,%*[^,],%lf,%c,%lf,%c", &lat, &ns, &lon, &ew) == 4) {
      double la = std::floor(lat / 100) + std::fmod(lat, 100) / 60;
      double lo = std::floor(lon / 100) + std::fmod(lon, 100) / 60;
      out.push_back({ns == 'S' ? -la : la, ew == 'W' ? -lo : lo});
    }
    ++at;
  }
  return out;
}

TEST(SimGnss, ServesTheOdometerDistanceAlongTheRouteOnAPty) {
  Scenario s = parse_scenario(R"toml(
[bike]
locks_locked = false
[[ride]]
duration_s = 5
speed_kmh = 0
[[ride]]
duration_s = 120
speed_kmh = 18
[[route]]
lat_deg = 52.5
lon_deg = 13.4
[[route]]
lat_deg = 52.5027
lon_deg = 13.4
)toml",
                              "gnss.toml");
  fleetgw::testing::TempDir dir;
  const auto link = dir.path() / "sim-gps";
  Bike bike(s);
  {
    SimGnss gnss(bike, link);
    ASSERT_TRUE(std::filesystem::is_symlink(link));
    const int fd = ::open(link.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK);
    ASSERT_GE(fd, 0);
    const RouteWalker route(s.route);
    std::string text;
    bool compared_mid = false;
    for (Micros t = s.start; t <= s.start + seconds(100); t += seconds(0.1)) {
      bike.advance_to(t, [](const motinova::CanFrame&) {});
      gnss.on_bus_time(t);
      const std::string got = drain(fd);
      text += got;
      const double along = bike.state().odo_m - s.odo_km * 1000;
      if (!got.empty() && along > 100 && along < 200 && !compared_mid) {
        // Mid-route: the fix is the point at the odometer's distance.
        const auto fixes = gga_positions(got);
        ASSERT_FALSE(fixes.empty()) << got;
        EXPECT_NEAR(great_circle_m(s.route[0], fixes.back()), along, 0.5);
        compared_mid = true;
      }
    }
    ::close(fd);
    EXPECT_TRUE(compared_mid);
    EXPECT_EQ(gnss.fixes_dropped(), 0u);
    EXPECT_NEAR(static_cast<double>(gnss.fixes_written()), 101, 1);  // 1 Hz of bus time
    const auto fixes = gga_positions(text);
    ASSERT_GT(fixes.size(), 90u);
    EXPECT_LT(great_circle_m(fixes.front(), s.route.front()), 0.1);  // parked at the start
    EXPECT_LT(great_circle_m(fixes[3], s.route.front()), 0.1);
    EXPECT_GT(bike.state().odo_m - s.odo_km * 1000, route.length_m());  // rode past the end
    EXPECT_LT(great_circle_m(fixes.back(), s.route.back()), 0.1);       // stays at the end
  }
  EXPECT_FALSE(std::filesystem::exists(link)) << "the link goes with the pty";
}

TEST(SimGnss, NoRouteIsAClearError) {
  const Bike bike(parse_scenario("", "empty.toml"));
  fleetgw::testing::TempDir dir;
  try {
    SimGnss gnss(bike, dir.path() / "gps");
    FAIL() << "accepted a scenario without a route";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("empty.toml has no [[route]]"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace fleetgw::sim
