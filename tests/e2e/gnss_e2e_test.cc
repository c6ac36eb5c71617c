// GNSS through the real `fleetgw run` (simulated bike) and a real gpsd fed by gpsfake (issue
// 14): the position reaches the telemetry samples, with its horizontal error from gpsd's TPV
// reports (issue 24); gpsd unreachable at start, gpsd gone mid-run and its return drive the IoT
// node's GNSS fault bit (0x0004) and "position unknown". The store is read with SQLite itself;
// every wait is for a condition with a deadline.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sqlite3.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "fleetgw/v1/telemetry.pb.h"
#include "tests/support/fake_gps.h"
#include "tests/support/gateway_config.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::FakeGps;
using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::have_gpsfake;
using fleetgw::testing::RoutePoint;
using fleetgw::testing::SqliteReader;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;
namespace v1 = fleetgw::v1;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;
constexpr int kIotNode = 6;
constexpr int kGpsBit = 2;  // 0x0004 in the normalised IoT fault word

struct Sample {
  std::int64_t seq;
  v1::TelemetrySample msg;
};

// Every telemetry sample in the outbox (the uplink is off: nothing is taken out).
std::vector<Sample> telemetry(const std::filesystem::path& db_path) {
  std::vector<Sample> out;
  SqliteReader(db_path).each(
      "SELECT seq, payload FROM outbox WHERE kind = 'telemetry' ORDER BY seq",
      [&](sqlite3_stmt* st) {
        Sample s{sqlite3_column_int64(st, 0), {}};
        const void* blob = sqlite3_column_blob(st, 1);
        if (blob != nullptr && s.msg.ParseFromArray(blob, sqlite3_column_bytes(st, 1))) {
          out.push_back(std::move(s));
        }
      });
  return out;
}

// Fault events of the GNSS bit, in order ("raised", "cleared", ...).
std::vector<std::string> gps_fault_events(const std::filesystem::path& db_path) {
  return SqliteReader(db_path).rows(
      "SELECT event FROM fault_events WHERE node = " + std::to_string(kIotNode) +
      " AND bit = " + std::to_string(kGpsBit) + " ORDER BY id");
}

std::filesystem::path write_config(const TempDir& dir, std::uint16_t gpsd_port) {
  GatewayConfig c("gnss-bike", dir / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/demo.toml", 1);
  c.set("storage", "flush_ms", "100").gnss(gpsd_port).set("gnss", "max_age_ms", "3000");
  c.set("telemetry", "riding_interval_ms", "500").set("telemetry", "parked_interval_ms", "1000");
  return c.write(dir / "fleetgw.toml");
}

bool on_route(const v1::Position& p) {
  const double lat = p.lat_e7() / 1e7;
  const double lon = p.lon_e7() / 1e7;
  return lat >= kLat0 - 1e-6 && lat <= kLat0 + 0.01 && std::abs(lon - kLon0) < 1e-6;
}

TEST(GnssEndToEnd, PositionReachesTelemetryAndTheFaultBitFollowsGpsd) {
  if (!have_gpsfake()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const auto db = dir.path() / "fleetgw.db";
  GatewayProcess gw(FLEETGW_BINARY, write_config(dir, port), {"--duration", "120"});

  // No gpsd yet: position unknown, the GNSS fault raised at once, no sample carries a position.
  ASSERT_TRUE(wait_until([&] { return !gps_fault_events(db).empty(); }, 20s)) << gw.log();
  EXPECT_EQ(gps_fault_events(db).front(), "raised");
  ASSERT_TRUE(wait_until([&] { return !telemetry(db).empty(); }, 20s)) << gw.log();
  for (const auto& s : telemetry(db)) {
    EXPECT_FALSE(s.msg.has_position()) << s.seq;
  }

  // gpsd comes up with a route north from (kLat0, kLon0), about 5 m a second.
  std::vector<RoutePoint> route;
  for (int i = 0; i < 120; ++i) route.push_back({kLat0 + i * 0.000045, kLon0});
  std::optional<FakeGps> gps;
  gps.emplace(dir, port, fleetgw::testing::nmea_route(route), FakeGps::Options{});
  std::int64_t first_fixed_seq = 0;
  ASSERT_TRUE(wait_until(
      [&] {
        for (const auto& s : telemetry(db)) {
          if (s.msg.has_position()) {
            first_fixed_seq = s.seq;
            return true;
          }
        }
        return false;
      },
      30s))
      << gw.log();
  // Positions are the route's, with the receiver's details.
  // The receiver's time: gpsd reports it once a sentence with the date (RMC) has arrived, so the
  // very first fix may carry none (0 = "receiver time unknown", never a made-up one); any time
  // reported is the route's day (2026-11-23, from the NMEA) -- not the gateway's clock.
  ASSERT_TRUE(wait_until(
      [&] {
        for (const auto& s : telemetry(db)) {
          if (s.msg.has_position() && s.msg.position().fixed_at_us() > 0) return true;
        }
        return false;
      },
      30s))
      << gw.log();
  constexpr std::int64_t kRouteDayUs = 1'795'392'000LL * 1'000'000;  // 2026-11-23T00:00:00Z
  int with_position = 0;
  for (const auto& s : telemetry(db)) {
    if (!s.msg.has_position()) continue;
    ++with_position;
    EXPECT_TRUE(on_route(s.msg.position())) << s.msg.position().lat_e7();
    const std::int64_t fixed_at = s.msg.position().fixed_at_us();
    if (fixed_at != 0) {
      EXPECT_GE(fixed_at, kRouteDayUs) << s.seq;
      EXPECT_LT(fixed_at, kRouteDayUs + 86'400LL * 1'000'000) << s.seq;
    }
  }
  EXPECT_GE(with_position, 1);
  // The accuracy of a receiver sending only GGA and RMC: gpsd sends TPV reports alone, whose eph
  // (17.1 m: the GGA's HDOP 0.9 times gpsd's range error) is the horizontal error. No SKY report
  // came, so no hdop and no satellite count -- never one made up from the eph.
  // A fix that gpsd reported before its first eph (the cycle's first TPV can come from the RMC
  // alone), or more than 2 s after the last one (a busy machine), carries none: never a stale or
  // made-up one. Every error carried is gpsd's, and the route's positions do carry it.
  ASSERT_TRUE(wait_until(
      [&] {
        for (const auto& s : telemetry(db)) {
          if (s.msg.has_position() && s.msg.position().has_horizontal_error_dm()) return true;
        }
        return false;
      },
      30s))
      << "no position carried gpsd's horizontal error\n"
      << gw.log();
  int with_error = 0;
  for (const auto& s : telemetry(db)) {
    if (!s.msg.has_position()) continue;
    const auto& p = s.msg.position();
    if (p.has_horizontal_error_dm()) {
      ++with_error;
      EXPECT_EQ(p.horizontal_error_dm(), 171u) << "seq " << s.seq;
    }
    if (p.has_hdop_centi()) {
      EXPECT_EQ(p.hdop_centi(), 90u) << "only the receiver's own HDOP";
    }
    if (p.has_satellites()) {
      EXPECT_EQ(p.satellites(), 8u) << "only the receiver's own count";
    }
  }
  EXPECT_GE(with_error, 1);
  // The fault clears once the fix holds for the fault debounce.
  ASSERT_TRUE(wait_until(
      [&] {
        const auto ev = gps_fault_events(db);
        return ev.size() >= 2 && ev[1] == "cleared";
      },
      20s))
      << gw.log();

  // gpsd gone mid-run: position unknown again at once, the fault raised again.
  gps->kill();
  gps.reset();
  ASSERT_TRUE(wait_until(
      [&] {
        const auto ev = gps_fault_events(db);
        return ev.size() >= 3 && ev[2] == "raised";
      },
      20s))
      << gw.log();
  std::int64_t after_loss = 0;
  for (const auto& s : telemetry(db)) after_loss = std::max(after_loss, s.seq);
  ASSERT_TRUE(wait_until(
      [&] {
        for (const auto& s : telemetry(db)) {
          if (s.seq > after_loss) return true;
        }
        return false;
      },
      20s));
  for (const auto& s : telemetry(db)) {
    if (s.seq > after_loss) {
      EXPECT_FALSE(s.msg.has_position()) << "stale position at " << s.seq;
    }
  }
  EXPECT_GT(first_fixed_seq, 0);
  EXPECT_EQ(gw.stop(), 0) << gw.log();
  EXPECT_TRUE(gw.log_contains("gnss: position unknown")) << gw.log();
}

}  // namespace

namespace {

// A "gpsd" that accepts and goes away without reading what the gateway sent (its WATCH
// request): the kernel answers the unread data with a reset, so the gateway's next write on
// that socket (libgps's gps_close() sends "?WATCH" to disable the stream) fails with EPIPE.
// Without SIGPIPE ignored, that write kills the process.
class ResettingGpsd {
 public:
  ResettingGpsd() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const int one = 1;
    ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 8) != 0) {
      throw std::runtime_error("ResettingGpsd: cannot listen");
    }
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~ResettingGpsd() { ::close(fd_); }
  std::uint16_t port() const { return port_; }
  // Accepts one connection (waiting at most `timeout`), waits until the client's request has
  // arrived, and closes with it unread: a reset. False when nobody connected.
  bool accept_and_reset(std::chrono::milliseconds timeout) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return false;
    const int c = ::accept(fd_, nullptr, nullptr);
    if (c < 0) return false;
    pollfd q{c, POLLIN, 0};
    ::poll(&q, 1, 10'000);  // the WATCH request (libgps sends it right after connecting)
    const linger hard{1, 0};
    ::setsockopt(c, SOL_SOCKET, SO_LINGER, &hard, sizeof hard);
    ::close(c);
    return true;
  }

 private:
  int fd_ = -1;
  std::uint16_t port_ = 0;
};

}  // namespace

// gpsd resetting its connections (a crash, a restart with data in flight) is a lost position,
// never a dead service: the gateway reconnects with its back-off and still stops cleanly.
TEST(GnssEndToEnd, AGpsdThatResetsItsConnectionsNeverKillsTheService) {
  TempDir dir("fleetgw-gnss-reset");
  ResettingGpsd gpsd;
  GatewayProcess gw(FLEETGW_BINARY, write_config(dir, gpsd.port()), {"--duration", "120"});
  // Each reconnect after a reset proves the service survived the write that followed it.
  int connections = 0;
  while (connections < 4 && gpsd.accept_and_reset(60s)) ++connections;
  EXPECT_EQ(connections, 4) << gw.log();
  EXPECT_TRUE(gw.running()) << "killed (exit " << gw.exit_code().value_or(-1) << ")\n" << gw.log();
  EXPECT_EQ(gw.stop(), 0) << gw.log();
}
