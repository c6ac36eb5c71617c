// `fleetgw sim --nmea-pty` (issue 14): the simulated bike as its own process, on a UDP bus,
// serving its scenario's [[route]] as NMEA on a pty exactly as `fleetgw run` does in-process.
// The real binary runs as a child; the test reads the pty itself (GGA+RMC, checksums, 1 Hz of
// bus time, positions on the route), then checks the link is gone once the process has ended
// (by its duration or by SIGTERM). A scenario without a route is a usage error (exit 2). With
// gpsd installed, a real gpsd on the pty reports the route's first waypoint (gpspipe).
#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/support/fake_gps.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::free_loopback_port;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

struct Point {
  double lat;
  double lon;
};

// 300 m north then 200 m east of Ljubljana's Prešeren Square.
constexpr Point kRoute[] = {{46.0514, 14.5061}, {46.0541, 14.5061}, {46.0541, 14.5087}};

double metres(const Point& a, const Point& b) {
  constexpr double kRad = M_PI / 180.0;
  const double dlat = (b.lat - a.lat) * kRad;
  const double dlon = (b.lon - a.lon) * kRad;
  const double h =
      std::sin(dlat / 2) * std::sin(dlat / 2) +
      std::cos(a.lat * kRad) * std::cos(b.lat * kRad) * std::sin(dlon / 2) * std::sin(dlon / 2);
  return 2 * 6'371'008.8 * std::asin(std::sqrt(h));
}

// Parked and unlocked for `parked_s` (the fixes stay on the first waypoint), then riding.
std::filesystem::path write_scenario(const TempDir& dir, bool with_route, int parked_s = 10) {
  const auto path = dir.file(with_route ? "routed.toml" : "no-route.toml");
  std::ofstream out(path);
  out << "[scenario]\nname = \"cli-route\"\n[bike]\nlocks_locked = false\n"
      << "[[ride]]\nduration_s = " << parked_s << "\nspeed_kmh = 0\n"
      << "[[ride]]\nduration_s = 300\nspeed_kmh = 20\n";
  if (with_route) {
    for (const Point& p : kRoute) {
      out << "[[route]]\nlat_deg = " << p.lat << "\nlon_deg = " << p.lon << '\n';
    }
  }
  return path;
}

std::vector<std::string> sim_argv(const std::filesystem::path& scenario,
                                  const std::filesystem::path& pty, const std::string& speed,
                                  const std::string& duration) {
  const std::string bus =
      "udp:" + std::to_string(free_loopback_port()) + ":" + std::to_string(free_loopback_port());
  return {FLEETGW_BIN, "sim", "--scenario", scenario.string(), "--bus",      bus,
          "--speed",   speed, "--duration", duration,          "--nmea-pty", pty.string()};
}

// Reads what the pty has (non-blocking); false once the writer's side is gone.
bool drain(int fd, std::string& into) {
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n > 0) {
      into.append(buf, static_cast<std::size_t>(n));
      continue;
    }
    return n < 0 && errno == EAGAIN;
  }
}

struct Sentence {
  std::string type;  // "GGA" / "RMC"
  std::string hms;   // hhmmss.ss
  Point position{};
};

double degrees(const std::string& ddmm, const std::string& hemi, int degree_digits) {
  const double deg = std::stod(ddmm.substr(0, degree_digits));
  const double min = std::stod(ddmm.substr(degree_digits));
  const double v = deg + min / 60.0;
  return hemi == "S" || hemi == "W" ? -v : v;
}

// Every line must be a whole, checksummed GGA or RMC sentence; fails the test otherwise.
std::vector<Sentence> parse_sentences(const std::string& text) {
  static const std::regex kLine(R"(^\$GP(GGA|RMC),([^*]*)\*([0-9A-F]{2})\r$)");
  std::vector<Sentence> out;
  std::size_t start = 0;
  for (std::size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1) {
    const std::string line = text.substr(start, nl - start);
    std::smatch m;
    if (!std::regex_match(line, m, kLine)) {
      ADD_FAILURE() << "not a GGA/RMC sentence: " << line;
      continue;
    }
    unsigned sum = 0;
    for (char c : line.substr(1, line.find('*') - 1)) sum ^= static_cast<unsigned char>(c);
    EXPECT_EQ(std::stoul(m[3].str(), nullptr, 16), sum) << "bad checksum: " << line;
    std::vector<std::string> f;
    std::stringstream fields(m[2].str());
    for (std::string item; std::getline(fields, item, ',');) f.push_back(item);
    Sentence s;
    s.type = m[1].str();
    // GGA: time,lat,N,lon,E,quality,...  RMC: time,status,lat,N,lon,E,...
    const std::size_t at = s.type == "GGA" ? 1 : 2;
    if (f.size() < at + 4) {
      ADD_FAILURE() << "short sentence: " << line;
      continue;
    }
    s.hms = f[0];
    s.position = {degrees(f[at], f[at + 1], 2), degrees(f[at + 2], f[at + 3], 3)};
    if (s.type == "GGA") {
      EXPECT_EQ(f[5], "1") << "fix quality: " << line;
    } else {
      EXPECT_EQ(f[1], "A") << "RMC status: " << line;
    }
    out.push_back(s);
  }
  EXPECT_EQ(start, text.size()) << "a partial sentence at the end";
  return out;
}

int seconds_of_day(const std::string& hms) {
  return std::stoi(hms.substr(0, 2)) * 3600 + std::stoi(hms.substr(2, 2)) * 60 +
         std::stoi(hms.substr(4, 2));
}

TEST(RunSimNmeaPty, StandaloneSimServesTheRouteOnThePtyAndRemovesTheLinkAtExit) {
  const TempDir dir("fleetgw-sim-nmea");
  const auto scenario = write_scenario(dir, true);
  const auto pty = dir.file("sim-gps");
  // 40 s of bus time at x20: two seconds of wall time, 41 fixes.
  ChildProcess sim(sim_argv(scenario, pty, "20", "40"), dir.file("sim.log"));
  ASSERT_TRUE(wait_until([&] { return std::filesystem::is_symlink(pty) || !sim.running(); }, 10s))
      << sim.log();
  ASSERT_TRUE(std::filesystem::is_symlink(pty)) << sim.log();
  const int fd = ::open(pty.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK);
  ASSERT_GE(fd, 0) << "open " << pty << ": " << std::strerror(errno);
  std::string text;
  // Read while it runs: the pty goes with the process (what it still held is lost then).
  wait_until([&] { return !drain(fd, text) || !sim.running(); }, 20s);
  drain(fd, text);
  ::close(fd);
  ASSERT_EQ(sim.wait_exit(10s), std::optional<int>(0)) << sim.log();
  EXPECT_FALSE(std::filesystem::exists(pty) || std::filesystem::is_symlink(pty))
      << "the link is removed at exit";

  // The text ends with a whole sentence; cut the last one if the exit cut it.
  const std::vector<Sentence> all = parse_sentences(text.substr(0, text.rfind('\n') + 1));
  std::vector<Sentence> gga;
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (all[i].type != "GGA") continue;
    gga.push_back(all[i]);
    // Each fix is GGA then RMC, same time and position.
    if (i + 1 < all.size()) {
      EXPECT_EQ(all[i + 1].type, "RMC");
      EXPECT_EQ(all[i + 1].hms, all[i].hms);
      EXPECT_LT(metres(all[i + 1].position, all[i].position), 0.05);
    }
  }
  ASSERT_GE(gga.size(), 35u) << text;
  for (std::size_t i = 1; i < gga.size(); ++i) {
    EXPECT_EQ(seconds_of_day(gga[i].hms) - seconds_of_day(gga[i - 1].hms), 1)
        << "1 Hz of bus time: " << gga[i - 1].hms << " then " << gga[i].hms;
  }
  EXPECT_EQ(gga.front().hms.substr(0, 6), "080000") << "the scenario starts at 08:00:00Z";
  // Parked: on the first waypoint (to the 0.00001' of the format, ~2 cm).
  for (std::size_t i = 0; i < 10; ++i) {
    EXPECT_LT(metres(gga[i].position, kRoute[0]), 0.1) << "fix " << i;
  }
  // Riding at 20 km/h: along the first leg (due north), ~5.6 m a second.
  const Sentence& last = gga.back();
  EXPECT_NEAR(last.position.lon, kRoute[0].lon, 1e-6);
  EXPECT_GT(last.position.lat, kRoute[0].lat);
  EXPECT_GT(metres(last.position, kRoute[0]), 100.0);
  EXPECT_LT(metres(last.position, kRoute[0]), metres(kRoute[0], kRoute[1]));
  EXPECT_TRUE(sim.log_contains("NMEA fixes written")) << sim.log();
}

TEST(RunSimNmeaPty, SigtermStopsItCleanlyAndRemovesTheLink) {
  const TempDir dir("fleetgw-sim-nmea");
  const auto pty = dir.file("sim-gps");
  ChildProcess sim(sim_argv(write_scenario(dir, true), pty, "1", "600"), dir.file("sim.log"));
  ASSERT_TRUE(wait_until([&] { return std::filesystem::is_symlink(pty) || !sim.running(); }, 10s))
      << sim.log();
  ASSERT_TRUE(std::filesystem::is_symlink(pty)) << sim.log();
  EXPECT_EQ(sim.stop(10s), 0) << sim.log();
  EXPECT_FALSE(std::filesystem::exists(pty) || std::filesystem::is_symlink(pty));
}

TEST(RunSimNmeaPty, ScenarioWithoutRouteIsAUsageErrorNamingTheFile) {
  const TempDir dir("fleetgw-sim-nmea");
  const auto scenario = write_scenario(dir, false);
  const auto pty = dir.file("sim-gps");
  const auto out = dir.file("sim.out");
  const int rc = fleetgw::testing::run_for_exit_code(sim_argv(scenario, pty, "1", "10"), out);
  EXPECT_EQ(rc, 2);
  const std::string log = fleetgw::testing::read_text_file(out);
  EXPECT_NE(log.find("scenario " + scenario.string() + " has no [[route]]"), std::string::npos)
      << log;
  EXPECT_NE(log.find("--nmea-pty"), std::string::npos) << log;
  EXPECT_FALSE(std::filesystem::is_symlink(pty)) << "no pty for a usage error";
}

// A real gpsd on the standalone simulator's pty, as on a bench with `gpsd -N -n -b`.
TEST(RunSimNmeaPty, RealGpsdReadsTheStandaloneSimulatorsPty) {
  if (!fleetgw::testing::have_gpsfake() || std::system("command -v gpspipe >/dev/null 2>&1")) {
    GTEST_SKIP() << "gpsd/gpspipe not installed (scripts/install-deps.sh)";
  }
  const TempDir dir("fleetgw-sim-nmea");
  const auto pty = dir.file("sim-gps");
  // Real time, parked for the first minute: gpsd sees the first waypoint.
  ChildProcess sim(sim_argv(write_scenario(dir, true, 60), pty, "1", "600"), dir.file("sim.log"));
  ASSERT_TRUE(wait_until([&] { return std::filesystem::is_symlink(pty) || !sim.running(); }, 10s))
      << sim.log();
  ASSERT_TRUE(std::filesystem::is_symlink(pty)) << sim.log();
  const std::string port = std::to_string(free_loopback_port());
  ChildProcess gpsd({"gpsd", "-N", "-n", "-b", "-S", port, pty.string()}, dir.file("gpsd.log"));
  // Until gpsd reports a 2D/3D fix from the pty (gpspipe may start before gpsd listens).
  std::optional<Point> fix;
  ASSERT_TRUE(wait_until(
      [&] {
        const auto out = dir.file("gpspipe.json");
        std::filesystem::remove(out);
        fleetgw::testing::run_for_exit_code(
            {"timeout", "3", "gpspipe", "-w", "-n", "12", "127.0.0.1:" + port}, out);
        std::ifstream in(out);
        for (std::string line; std::getline(in, line);) {
          const auto j = nlohmann::json::parse(line, nullptr, false);
          if (j.is_object() && j.value("class", "") == "TPV" && j.value("mode", 0) >= 2 &&
              j.contains("lat") && j.contains("lon")) {
            fix = Point{j["lat"].get<double>(), j["lon"].get<double>()};
          }
        }
        return fix.has_value();
      },
      40s, 100ms))
      << sim.log() << gpsd.log();
  EXPECT_LT(metres(*fix, kRoute[0]), 0.5);
  gpsd.stop(5s);
  EXPECT_EQ(sim.stop(10s), 0) << sim.log();
}

}  // namespace
