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
#include <mqtt/async_client.h>
#include <signal.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/nmea.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::RoutePoint;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

constexpr double kLat0 = 52.5200;
constexpr double kLon0 = 13.4050;
constexpr double kStepDeg = 0.000045;  // about 5 m a second, north

bool have_gpsd_tools() {
  return std::system("command -v gpsfake >/dev/null 2>&1 && command -v gpsd >/dev/null 2>&1") == 0;
}

// gpsfake and its gpsd in a process group of their own, ended together.
class ZoneGps {
 public:
  ZoneGps(const TempDir& dir, std::uint16_t port, const std::string& nmea) {
    const auto file = dir.path() / "route.nmea";
    std::ofstream(file) << nmea;
    process_.emplace(std::vector<std::string>{"setsid", "gpsfake", "-q", "-c", "0.5", "-P",
                                              std::to_string(port), "-S", file.string()},
                     dir.path() / "gpsfake.log");
  }
  ~ZoneGps() {
    ::kill(-process_->pid(), SIGKILL);
    process_->kill();
  }
  ZoneGps(const ZoneGps&) = delete;
  ZoneGps& operator=(const ZoneGps&) = delete;

 private:
  std::optional<ChildProcess> process_;
};

std::string run_tool(const TempDir& dir, const std::vector<std::string>& args) {
  std::vector<std::string> argv{FLEETGW_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto out = dir.path() / "tool.out";
  std::filesystem::remove(out);
  fleetgw::testing::run_program(argv, out);
  std::ifstream in(out);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

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
  if (!have_gpsd_tools()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  // The operator's side: a key, the zone drawn as GeoJSON, the signed bundle.
  const std::string keygen = run_tool(dir, {"keygen", (dir.path() / "ops").string()});
  const auto key_line = keygen.substr(keygen.find("ops = \""));
  const double lat_in = kLat0 + 20 * kStepDeg, lat_out = kLat0 + 0.02;
  std::ofstream(dir.path() / "zones.geojson")
      << R"({"type": "FeatureCollection", "features": [{"type": "Feature",
        "properties": {"id": "old-town", "kind": "slow", "speed_limit_kmh": 15},
        "geometry": {"type": "Polygon", "coordinates": [[)"
      << "[" << kLon0 - 0.002 << "," << lat_in << "],[" << kLon0 + 0.002 << "," << lat_in << "],["
      << kLon0 + 0.002 << "," << lat_out << "],[" << kLon0 - 0.002 << "," << lat_out << "]"
      << "]]}}]}";
  const auto bundle = dir.path() / "zones.pb";
  run_tool(dir, {"zones", "sign", (dir.path() / "zones.geojson").string(), "--version", "1",
                 "--key", (dir.path() / "ops.pem").string(), "--out", bundle.string()});

  // The bike's side: the bundle already stored, the uplink on but its broker down (nothing
  // listens on its port): the zones must not wait for it.
  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const std::uint16_t broker_port = fleetgw::testing::free_loopback_port();
  std::ostringstream c;
  c << "[vehicle]\nid = \"zone-bike\"\n[log]\nlevel = \"info\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/demo.toml\"\nspeed = 1\n"
    << "[storage]\npath = \"" << (dir.path() / "fleetgw.db").string() << "\"\n"
    << "[status]\nsocket = \"\"\n"
    << "[mqtt]\nenabled = true\nuri = \"tcp://127.0.0.1:" << broker_port << "\"\n"
    << "[gnss]\nenabled = true\ngpsd = \"127.0.0.1:" << port << "\"\nreconnect_max_ms = 1000\n"
    << "[geofence]\nenabled = true\nbundle_file = \"" << bundle.string() << "\"\n"
    << "margin_m = 5\nmin_dwell_ms = 2000\nspeed_ramp_ms = 3000\nrestore_ramp_ms = 2000\n"
    << "[command.trusted_keys]\n"
    << key_line.substr(0, key_line.find('\n')) << "\n";
  const auto config = dir.path() / "fleetgw.toml";
  std::ofstream(config) << c.str();
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "240"});
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("geofence: version 1 in force"); }, 20s))
      << gw.log();

  // North for 40 s (the zone begins 20 s in), back south for 40 s, then 30 s south of it.
  std::vector<RoutePoint> route;
  for (int i = 0; i < 40; ++i) route.push_back({kLat0 + i * kStepDeg, kLon0});
  for (int i = 40; i > 0; --i) route.push_back({kLat0 + i * kStepDeg, kLon0});
  for (int i = 0; i < 30; ++i) route.push_back({kLat0, kLon0});
  ZoneGps gps(dir, port, fleetgw::testing::nmea_route(route));

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

// Zone events and alarms as a backend decodes them from the broker.
class ZoneSubscriber {
 public:
  ZoneSubscriber(const std::string& uri, const std::string& vehicle)
      : client_(uri, "zone-e2e-" + std::to_string(getpid())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      std::lock_guard lock(mutex_);
      if (!e.ParseFromString(m->get_payload())) return;
      if (e.has_zone()) zones_.push_back({m->get_topic(), e.zone()});
      if (e.has_alarm()) alarms_.push_back({m->get_topic(), e.alarm()});
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + vehicle + "/#", 1)->wait();
  }
  ~ZoneSubscriber() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {
    }
  }
  template <typename M>
  struct Received {
    std::string topic;
    M message;
  };
  std::vector<Received<fleetgw::v1::ZoneEvent>> zones() {
    std::lock_guard lock(mutex_);
    return zones_;
  }
  std::vector<Received<fleetgw::v1::Alarm>> alarms() {
    std::lock_guard lock(mutex_);
    return alarms_;
  }
  // "<zone id> <transition number>" in arrival order, for one readable comparison.
  std::vector<std::string> zone_log() {
    std::vector<std::string> out;
    for (const auto& z : zones()) {
      out.push_back(z.message.zone_id() + " " + std::to_string(z.message.transition()));
    }
    return out;
  }
  bool has_zone(const std::string& id, fleetgw::v1::ZoneTransition t) {
    const auto log = zone_log();
    return std::find(log.begin(), log.end(), id + " " + std::to_string(t)) != log.end();
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::vector<Received<fleetgw::v1::ZoneEvent>> zones_;
  std::vector<Received<fleetgw::v1::Alarm>> alarms_;
};

// Rows of one query as "a|b|c" lines (NULL as "-").
std::vector<std::string> query(const std::filesystem::path& db, const std::string& sql) {
  std::vector<std::string> rows;
  sqlite3* h = nullptr;
  if (sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    sqlite3_close(h);
    ADD_FAILURE() << "cannot open " << db;
    return rows;
  }
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(h, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
    ADD_FAILURE() << sql << ": " << sqlite3_errmsg(h);
    sqlite3_close(h);
    return rows;
  }
  while (sqlite3_step(st) == SQLITE_ROW) {
    std::string row;
    for (int i = 0; i < sqlite3_column_count(st); ++i) {
      if (i > 0) row += "|";
      const auto* t = sqlite3_column_text(st, i);
      row += t ? reinterpret_cast<const char*>(t) : "-";
    }
    rows.push_back(row);
  }
  sqlite3_finalize(st);
  sqlite3_close(h);
  return rows;
}

std::string rect(double lon0, double lon1, double lat0, double lat1) {
  std::ostringstream o;
  o.precision(9);
  o << "[[[" << lon0 << "," << lat0 << "],[" << lon1 << "," << lat0 << "],[" << lon1 << "," << lat1
    << "],[" << lon0 << "," << lat1 << "]]]";
  return o.str();
}

TEST(GeofenceEndToEnd, ZoneEventsTheAreaAlarmAndARefusedLockReachTheBrokerAndTheStore) {
  if (!have_gpsd_tools()) GTEST_SKIP() << "gpsd/gpsfake not installed (scripts/install-deps.sh)";
  TempDir dir;
  MosquittoBroker broker;
  broker.start();
  const std::string vehicle = "zone-bike-2";
  ZoneSubscriber sub(broker.uri(), vehicle);

  // 10 m a second, north. The operating area ends 150 m north; the slow zone starts 50 m north;
  // the bike starts (and stops) in a no-parking zone that ends 20 m north.
  constexpr double kStep = 2 * kStepDeg;
  const double w = kLon0 - 0.002, e = kLon0 + 0.002;
  const std::string keygen = run_tool(dir, {"keygen", (dir.path() / "ops").string()});
  const auto key_line = keygen.substr(keygen.find("ops = \""));
  std::ofstream(dir.path() / "zones.geojson")
      << R"({"type": "FeatureCollection", "features": [)"
      << R"({"type": "Feature", "properties": {"id": "city", "kind": "operating_area"},)"
      << R"("geometry": {"type": "Polygon", "coordinates": )"
      << rect(w, e, kLat0 - 0.001, kLat0 + 15 * kStep) << "}},"
      << R"({"type": "Feature", "properties": {"id": "old-town", "kind": "slow", )"
      << R"("speed_limit_kmh": 15}, "geometry": {"type": "Polygon", "coordinates": )"
      << rect(w, e, kLat0 + 5 * kStep, kLat0 + 0.02) << "}},"
      << R"({"type": "Feature", "properties": {"id": "station", "kind": "no_parking"},)"
      << R"("geometry": {"type": "Polygon", "coordinates": )"
      << rect(w, e, kLat0 - 0.0005, kLat0 + 2 * kStep) << "}}]}";
  const auto bundle = dir.path() / "zones.pb";
  const std::string signed_out =
      run_tool(dir, {"zones", "sign", (dir.path() / "zones.geojson").string(), "--version", "3",
                     "--key", (dir.path() / "ops.pem").string(), "--out", bundle.string()});
  ASSERT_TRUE(std::filesystem::exists(bundle)) << signed_out;

  const std::uint16_t port = fleetgw::testing::free_loopback_port();
  const auto db = dir.path() / "fleetgw.db";
  std::ostringstream c;
  c << "[vehicle]\nid = \"" << vehicle << "\"\n[log]\nlevel = \"info\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/parked.toml\"\nspeed = 1\n"
    << "[storage]\npath = \"" << db.string() << "\"\n"
    << "[status]\nsocket = \"\"\n"
    << "[mqtt]\nenabled = true\nuri = \"" << broker.uri() << "\"\n"
    << "reconnect_min_ms = 100\nreconnect_max_ms = 500\n"
    << "[gnss]\nenabled = true\ngpsd = \"127.0.0.1:" << port << "\"\nreconnect_max_ms = 1000\n"
    << "[geofence]\nenabled = true\nbundle_file = \"" << bundle.string() << "\"\n"
    << "margin_m = 5\nmin_dwell_ms = 2000\nspeed_ramp_ms = 3000\nrestore_ramp_ms = 2000\n"
    << "refuse_ride_ending_locks = true\n"
    << "[command.trusted_keys]\n"
    << key_line.substr(0, key_line.find('\n')) << "\n";
  const auto config = dir.path() / "fleetgw.toml";
  std::ofstream(config) << c.str();
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
  ZoneGps gps(dir, port, fleetgw::testing::nmea_route(route));

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
       "--key", (dir.path() / "ops.pem").string(), "--broker", broker.uri(), "--timeout-s", "30"},
      out);
  std::ifstream in(out);
  const std::string result((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
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
