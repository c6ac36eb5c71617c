// `fleetgw serve` (issue 28): the operator API over the ingest's tables, the console's files,
// headers and limits, live updates, TLS, against the real fleetgw-serve over PostgreSQL.
#include <gtest/gtest.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <thread>

#include "tests/support/wait.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
constexpr const char* kScriptId = "<script>alert('x')</script>";

class WebApi : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ = std::make_unique<ServeStack>();
    ASSERT_EQ(stack_->add_operator("olga", "operator", "operator-password"), 0);
    const std::int64_t t = now_us();
    stack_->insert_vehicle({.id = "parked-bike", .lat = 48.10, .lon = 11.50});
    stack_->insert_vehicle(
        {.id = "riding-bike", .lat = 48.12, .lon = 11.52, .mode = "VEHICLE_MODE_RIDING"});
    stack_->insert_vehicle({.id = "flat-bike", .lat = 48.11, .lon = 11.49, .soc_pct = 12});
    stack_->insert_vehicle({.id = "gone-bike", .lat = 48.09, .lon = 11.51, .status_online = false});
    stack_->insert_vehicle({.id = kScriptId, .lat = 48.13, .lon = 11.53});
    stack_->insert_vehicle({.id = "stolen-bike", .lat = 48.14, .lon = 11.54});
    // A raised alarm that is still active, and one raised then cleared.
    stack_->insert_alarm("stolen-bike", 1, "ALARM_KIND_UNAUTHORISED_MOVEMENT",
                         "ALARM_TRANSITION_RAISED", t - 5'000'000, "<img src=x onerror=alert(1)>");
    stack_->insert_alarm("parked-bike", 1, "ALARM_KIND_LOCK_TAMPER", "ALARM_TRANSITION_RAISED",
                         t - 9'000'000);
    stack_->insert_alarm("parked-bike", 2, "ALARM_KIND_LOCK_TAMPER", "ALARM_TRANSITION_CLEARED",
                         t - 8'000'000);
    // A ride of riding-bike with its track, and its current lock.
    for (int i = 0; i < 5; ++i) {
      stack_->insert_sample("riding-bike", i + 1, t - 60'000'000 + i * 1'000'000, 150 + i,
                            48.12 + i * 0.001, 11.52);
    }
    const fleetgw::PgParam ride[] = {std::to_string(t - 60'000'000),
                                     std::to_string(t - 56'000'000)};
    stack_->db().query(
        "INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
        "ride_id, started_at_us, ended_at_us, distance_odo_m, max_speed_dkmh, soc_start_pct, "
        "soc_end_pct) VALUES ('riding-bike', 'store-1', 10, $2, '0.1.0', 'ride-1', $1, $2, 420, "
        "154, 90, 88)",
        ride, "ride row");
    stack_->insert_lock("riding-bike", 11, "open");
    login_ = stack_->login("olga", "operator-password");
    ASSERT_EQ(login_.status, 200);
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  static json get(const std::string& path, int expected_status = 200) {
    auto res = stack_->client().Get(path, {{"Cookie", login_.cookie}});
    EXPECT_TRUE(res) << path;
    if (!res) return nullptr;
    EXPECT_EQ(res->status, expected_status) << path << ": " << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json; charset=utf-8");
    EXPECT_EQ(res->get_header_value("Cache-Control"), "no-store");
    return json::parse(res->body);
  }

  static json fleet_vehicle(const std::string& id) {
    const json fleet = get("/api/fleet");
    for (const json& v : fleet["vehicles"]) {
      if (v["id"] == id) return v;
    }
    ADD_FAILURE() << "no vehicle " << id << " in " << fleet.dump();
    return json::object();
  }

  static std::unique_ptr<ServeStack> stack_;
  static LoginResult login_;
};
std::unique_ptr<ServeStack> WebApi::stack_;
LoginResult WebApi::login_;

TEST_F(WebApi, FleetColoursEachVehicleByItsState) {
  const json fleet = get("/api/fleet")["vehicles"];
  ASSERT_EQ(fleet.size(), 6u);
  std::map<std::string, std::string> states;
  for (const json& v : fleet) states[v["id"]] = v["state"];
  EXPECT_EQ(states["parked-bike"], "parked");  // its tamper alarm was cleared
  EXPECT_EQ(states["riding-bike"], "riding");
  EXPECT_EQ(states["flat-bike"], "low_battery");
  EXPECT_EQ(states["gone-bike"], "offline");
  EXPECT_EQ(states["stolen-bike"], "alarm");

  const json riding = fleet_vehicle("riding-bike");
  EXPECT_NEAR(riding["lat"].get<double>(), 48.12, 1e-6);
  EXPECT_NEAR(riding["lon"].get<double>(), 11.52, 1e-6);
  EXPECT_DOUBLE_EQ(riding["speed_kmh"].get<double>(), 15.4);  // the latest sample
  ASSERT_EQ(riding["locks"].size(), 1u);
  EXPECT_EQ(riding["locks"][0]["name"], "open");
  const json stolen = fleet_vehicle("stolen-bike");
  EXPECT_EQ(stolen["alarms"]["kinds"], json({"ALARM_KIND_UNAUTHORISED_MOVEMENT"}));
  EXPECT_EQ(stolen["alarms"]["unacked"], 1);
}

TEST_F(WebApi, AVehicleIdHoldingMarkupComesBackAsTheSameJsonString) {
  const json v = fleet_vehicle(kScriptId);
  ASSERT_FALSE(v.is_null());
  EXPECT_EQ(v["id"], kScriptId);
  // Reachable by its id, percent-encoded as the console does it.
  const json page = get("/api/vehicles/%3Cscript%3Ealert('x')%3C%2Fscript%3E");
  EXPECT_EQ(page["id"], kScriptId);
  auto res = stack_->client().Get("/api/fleet", {{"Cookie", login_.cookie}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->get_header_value("X-Content-Type-Options"), "nosniff");
}

TEST_F(WebApi, VehiclePageHasRidesWithTrackAlarmsAndStatus) {
  const json v = get("/api/vehicles/riding-bike");
  ASSERT_EQ(v["rides"].size(), 1u);
  EXPECT_EQ(v["rides"][0]["ride_id"], "ride-1");
  EXPECT_EQ(v["rides"][0]["track"].size(), 5u);
  EXPECT_NEAR(v["rides"][0]["track"][4][0].get<double>(), 48.124, 1e-6);
  EXPECT_EQ(v["status"]["connection"], "CONNECTION_STATE_CONNECTED");
  const json parked = get("/api/vehicles/parked-bike");
  ASSERT_EQ(parked["alarm_history"].size(), 2u);
  EXPECT_EQ(parked["alarm_history"][0]["transition"], "ALARM_TRANSITION_CLEARED");
  EXPECT_FALSE(parked["alarm_history"][1]["active"].get<bool>());
  get("/api/vehicles/no-such-bike", 404);
}

TEST_F(WebApi, AlarmFeedShowsTheAcknowledgementWhoAndWhen) {
  json feed = get("/api/alarms");
  ASSERT_EQ(feed["alarms"].size(), 3u);
  json stolen;
  for (const json& a : feed["alarms"]) {
    if (a["vehicle_id"] == "stolen-bike") stolen = a;
  }
  ASSERT_FALSE(stolen.is_null());
  EXPECT_TRUE(stolen["active"].get<bool>());
  EXPECT_EQ(stolen["detail"], "<img src=x onerror=alert(1)>");
  EXPECT_TRUE(stolen["acked_by"].is_null());
  const std::int64_t before = now_us();
  auto res = stack_->client().Post("/api/alarms/" + stolen["id"].get<std::string>() + "/ack",
                                   {{"Cookie", login_.cookie}, {"X-CSRF-Token", login_.csrf}}, "",
                                   "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  const json after = get("/api/alarms");  // named: a temporary's member would dangle in the loop
  for (const json& a : after["alarms"]) {
    if (a["vehicle_id"] != "stolen-bike") continue;
    EXPECT_EQ(a["acked_by"], "olga");
    EXPECT_GE(a["acked_at_us"].get<std::int64_t>(), before);
  }
  EXPECT_EQ(fleet_vehicle("stolen-bike")["alarms"]["unacked"], 0);
  // A malformed or unknown id is refused, not stored.
  for (const std::string id : {"zz.11.1", "6e6f.73746f72652d31.99"}) {
    auto bad = stack_->client().Post("/api/alarms/" + id + "/ack",
                                     {{"Cookie", login_.cookie}, {"X-CSRF-Token", login_.csrf}}, "",
                                     "application/json");
    ASSERT_TRUE(bad);
    EXPECT_EQ(bad->status, id.starts_with("zz") ? 400 : 404) << id;
  }
}

TEST_F(WebApi, ConsoleFilesCarryAStrictContentSecurityPolicy) {
  auto res = stack_->client().Get("/");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_NE(res->body.find("fleetgw console"), std::string::npos);
  const std::string csp = res->get_header_value("Content-Security-Policy");
  EXPECT_NE(csp.find("frame-ancestors 'none'"), std::string::npos) << csp;
  EXPECT_NE(csp.find("script-src 'self'"), std::string::npos) << csp;
  EXPECT_EQ(csp.find("unsafe-inline"), std::string::npos) << csp;
  EXPECT_EQ(res->get_header_value("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(res->get_header_value("X-Frame-Options"), "DENY");
  auto leaflet = stack_->client().Get("/vendor/leaflet/leaflet.js");
  ASSERT_TRUE(leaflet);
  EXPECT_EQ(leaflet->status, 200);
  auto escape = stack_->client().Get("/../../etc/passwd");
  ASSERT_TRUE(escape);
  EXPECT_NE(escape->status, 200);
}

TEST_F(WebApi, OversizedRequestBodiesAreRefused) {
  auto res = stack_->client().Post("/api/login", std::string(100 * 1024, 'x'), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 413);
}

TEST_F(WebApi, EventStreamAnnouncesANewAlarm) {
  std::atomic<bool> seen_alarm{false};
  std::atomic<bool> connected{false};
  std::string received;
  std::thread reader([&] {
    httplib::Client c = stack_->client();
    c.Get("/api/events", {{"Cookie", login_.cookie}}, [&](const char* data, std::size_t n) {
      connected = true;
      received.append(data, n);
      if (received.find("event: alarms") != std::string::npos) seen_alarm = true;
      return !seen_alarm;  // false: stop reading
    });
  });
  ASSERT_TRUE(wait_until([&] { return connected.load(); }, std::chrono::seconds(10)));
  stack_->insert_alarm("gone-bike", 7, "ALARM_KIND_BATTERY_REMOVED", "ALARM_TRANSITION_RAISED",
                       now_us());
  EXPECT_TRUE(wait_until([&] { return seen_alarm.load(); }, std::chrono::seconds(10)));
  reader.join();
  EXPECT_NE(received.find("event: fleet"), std::string::npos) << received;
}

// Under TLS the session cookie is Secure and browsers are told to stay on HTTPS.
TEST(WebServe, HttpsSessionCookieIsSecureAndHstsIsSent) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  ServeStack stack({}, /*tls=*/true);
  ASSERT_EQ(stack.add_operator("olga", "operator", "operator-password"), 0);
  const LoginResult l = stack.login("olga", "operator-password");
  ASSERT_EQ(l.status, 200) << stack.log();
  EXPECT_NE(l.set_cookie.find("; Secure"), std::string::npos) << l.set_cookie;
  EXPECT_NE(l.set_cookie.find("HttpOnly"), std::string::npos) << l.set_cookie;
  auto res = stack.client().Get("/api/fleet", {{"Cookie", l.cookie}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Strict-Transport-Security"), "max-age=31536000");
}

// Plain HTTP off loopback is refused before anything is bound.
TEST(WebServe, PlainHttpOnANonLoopbackAddressNeedsInsecureHttp) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  PostgresCluster pg;
  TempDir dir("fleetgw-web-plain");
  const int rc = run_for_exit_code({FLEETGW_SERVE_BINARY, "--pg", pg.conninfo(), "--listen",
                                    "0.0.0.0:" + std::to_string(free_loopback_port())},
                                   dir / "out.log");
  EXPECT_EQ(rc, 1);
  EXPECT_NE(read_text_file(dir / "out.log").find("--insecure-http"), std::string::npos)
      << read_text_file(dir / "out.log");
}

}  // namespace
}  // namespace fleetgw::testing
