// The console's vehicle page and campaign page (issues 28 and 29) and the cached fleet list,
// against the real fleetgw-serve over PostgreSQL with rows in the ingest's tables: a ride's
// samples for its plot, the speed limit in force and why, the campaigns seen with their
// vehicles, samples and CSV (formula cells neutralised), who may read them; and the fleet list
// served from its cache with an ETag (304), gzip and a compact view, rebuilt after a change.
// The browser half (browser/console_pages_test.mjs): the ride's track drawn and the plot's
// points present, hostile strings shown as text, the campaign page's plot and table.
#include <gtest/gtest.h>

#include <cctype>
#include <map>
#include <nlohmann/json.hpp>
#include <string_view>

#include "tests/support/wait.h"
#include "tests/web/web_command_e2e.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;
constexpr const char* kPagesHostileId = "<script>window.__xss=1</script>";
constexpr const char* kPagesHostileRide = "ride-<img src=x onerror=window.__xss=2>";
constexpr const char* kPagesHostileCampaign = "=HYPERLINK(\"http://evil\")";
constexpr int kPagesRideSamples = 30;

// Percent-encoding of a query value (every byte but unreserved ones).
std::string pages_pct(std::string_view s) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char ch : s) {
    const auto b = static_cast<unsigned char>(ch);
    if (std::isalnum(b) || ch == '-' || ch == '_' || ch == '.' || ch == '~') {
      out += ch;
    } else {
      out += '%';
      out += kHex[b >> 4];
      out += kHex[b & 15];
    }
  }
  return out;
}

class WebPages : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ = std::make_unique<ServeStack>();
    ASSERT_EQ(stack_->add_operator("vera", "viewer", "viewer-password"), 0);
    t_ = now_us();
    stack_->insert_vehicle({.id = "ride-bike", .lat = 48.10, .lon = 11.50});
    stack_->insert_vehicle({.id = kPagesHostileId, .lat = 48.11, .lon = 11.51});
    // A ride of each: 30 samples, a second apart, going north-east, speed/power/SOC moving.
    for (const std::string v : {"ride-bike", kPagesHostileId}) {
      const std::string ride = v == "ride-bike" ? "ride-1" : kPagesHostileRide;
      stack_->rows(
          "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
          "sampled_at_us, speed_dkmh, power_w, soc_pct, lat_e7, lon_e7) SELECT $1, 's', i, "
          "$2::bigint + i * 1000000, $2::bigint + i * 1000000, 100 + i * 5, 200 + i * 10, "
          "90 - i / 10, 481000000 + i * 1000, 115000000 + i * 1500 FROM generate_series(0, 29) i",
          {v, std::to_string(t_ - 100'000'000)});
      stack_->rows(
          "INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
          "ride_id, started_at_us, ended_at_us, distance_odo_m, max_speed_dkmh, soc_start_pct, "
          "soc_end_pct) VALUES ($1, 's', 1000, $3::bigint, '0.1.0', $2, $4::bigint, $3::bigint, "
          "300, 245, 90, 88)",
          {v, ride, std::to_string(t_ - 100'000'000 + 29'000'000),
           std::to_string(t_ - 100'000'000)});
    }
    // The limit in force and why: the MC reports 12 km/h; olga capped it at 20; the bike is in
    // the slow zone "Old <b>Town</b>" (12) and has left "Harbour".
    stack_->rows("UPDATE vehicle_state SET speed_limit_dkmh = 120 WHERE vehicle_id = 'ride-bike'");
    stack_->rows(
        "INSERT INTO console_commands (command_id, vehicle_id, operator, address, action, "
        "params, key_id, command_sha256, payload_sha256, issued_at_us, expires_at_us, result, "
        "result_at_us, limit_in_force) VALUES ('c1', 'ride-bike', 'olga', '127.0.0.1', "
        "'speed_limit', 'speed_limit 20 km/h', 'console-1', '', '', $1::bigint, $1::bigint, "
        "'succeeded', $1::bigint, 'capped at 20; 12 in force inside ''Old <b>Town</b>''')",
        {std::to_string(t_ - 50'000'000)});
    int seq = 1;
    for (const auto& [zone, name, transition] :
         std::vector<std::tuple<std::string, std::string, std::string>>{
             {"z-old", "Old <b>Town</b>", "ZONE_TRANSITION_ENTER"},
             {"z-harbour", "Harbour", "ZONE_TRANSITION_ENTER"},
             {"z-harbour", "Harbour", "ZONE_TRANSITION_EXIT"}}) {
      stack_->rows(
          "INSERT INTO zone_events (vehicle_id, store_id, sequence, created_at_us, "
          "gateway_fw_version, zone_id, zone_name, kind, transition, at_us, speed_limit_kmh) "
          "VALUES ('ride-bike', 's', $1::bigint, $2::bigint, '0.1.0', $3, $4, 'ZONE_KIND_SLOW', "
          "$5, $2::bigint, 12)",
          {std::to_string(seq), std::to_string(t_ - 40'000'000 + seq * 1'000'000), zone, name,
           transition});
      ++seq;
    }
    // Campaign samples: hot-pack v3 from two bikes (a pack temperature, 10 each); a campaign
    // whose id and text values are formulas.
    stack_->rows(
        "INSERT INTO campaign_samples (vehicle_id, store_id, sequence, sample_index, "
        "created_at_us, gateway_fw_version, campaign_id, campaign_version, signal, "
        "sampled_at_us, value_e6, invalid) SELECT v, 's', 1, i, $1::bigint, '0.1.0', "
        "'hot-pack', 3, 'bms.pack_temp_c', $1::bigint + i * 1000000, (40 + i) * 1000000 - "
        "CASE WHEN v = 'ride-bike' THEN 0 ELSE 45500000 END, false "
        "FROM generate_series(0, 9) i, (VALUES ('ride-bike'), ($2)) b(v)",
        {std::to_string(t_ - 30'000'000), kPagesHostileId});
    stack_->rows(
        "INSERT INTO campaign_samples (vehicle_id, store_id, sequence, sample_index, "
        "created_at_us, gateway_fw_version, campaign_id, campaign_version, signal, "
        "sampled_at_us, text, invalid) VALUES ('ride-bike', 's', 2, 0, $1::bigint, '0.1.0', $2, "
        "1, 'mc.model', $1::bigint, '=cmd|'' /C calc''!A0', false)",
        {std::to_string(t_ - 20'000'000), kPagesHostileCampaign});
    viewer_ = stack_->login("vera", "viewer-password");
    ASSERT_EQ(viewer_.status, 200);
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  static httplib::Result get(const std::string& path, httplib::Headers extra = {}) {
    extra.emplace("Cookie", viewer_.cookie);
    return stack_->client().Get(path, extra);
  }
  static json get_json(const std::string& path) {
    auto res = get(path);
    EXPECT_TRUE(res) << path;
    if (!res) return nullptr;
    EXPECT_EQ(res->status, 200) << path << ": " << res->body;
    return json::parse(res->body, nullptr, false);
  }

  static std::unique_ptr<ServeStack> stack_;
  static LoginResult viewer_;
  static std::int64_t t_;
};
std::unique_ptr<ServeStack> WebPages::stack_;
LoginResult WebPages::viewer_;
std::int64_t WebPages::t_ = 0;

TEST_F(WebPages, EveryNewReadNeedsASessionAndAViewerMayReadThem) {
  for (const std::string path :
       {"/api/campaigns", "/api/campaigns/detail?id=hot-pack&version=3",
        "/api/campaigns/samples?id=hot-pack&version=3&signal=bms.pack_temp_c",
        "/api/campaigns/samples.csv?id=hot-pack&version=3",
        "/api/rides?vehicle=ride-bike&ride=ride-1", "/api/fleet?view=compact"}) {
    auto anonymous = stack_->client().Get(path);
    ASSERT_TRUE(anonymous) << path;
    EXPECT_EQ(anonymous->status, 401) << path;
    auto viewer = get(path);
    ASSERT_TRUE(viewer) << path;
    EXPECT_EQ(viewer->status, 200) << path << ": " << viewer->body;
  }
}

TEST_F(WebPages, CampaignsSeenWithTheirVehiclesSamplesAndOneSignal) {
  const json list = get_json("/api/campaigns");
  ASSERT_TRUE(list["available"].get<bool>());
  ASSERT_EQ(list["campaigns"].size(), 2u) << list.dump();
  json hot;
  for (const json& c : list["campaigns"]) {
    if (c["id"] == "hot-pack") hot = c;
  }
  ASSERT_FALSE(hot.is_null()) << list.dump();
  EXPECT_EQ(hot["version"], 3);
  EXPECT_EQ(hot["vehicles"], 2);
  EXPECT_EQ(hot["samples"], 20);
  EXPECT_EQ(hot["signals"], json({"bms.pack_temp_c"}));
  EXPECT_EQ(hot["last_sample_us"], t_ - 30'000'000 + 9'000'000);

  const json detail = get_json("/api/campaigns/detail?id=hot-pack&version=3");
  ASSERT_EQ(detail["vehicles"].size(), 2u);
  std::map<std::string, json> by_id;
  for (const json& v : detail["vehicles"]) by_id[v["vehicle_id"]] = v;
  ASSERT_TRUE(by_id.contains(kPagesHostileId)) << detail.dump();
  EXPECT_EQ(by_id["ride-bike"]["samples"], 10);
  EXPECT_EQ(by_id["ride-bike"]["last_sample_us"], t_ - 30'000'000 + 9'000'000);

  const json one = get_json(
      "/api/campaigns/samples?id=hot-pack&version=3&signal=bms.pack_temp_c&vehicle=ride-bike");
  ASSERT_EQ(one["samples"].size(), 10u);
  EXPECT_DOUBLE_EQ(one["samples"][0][2].get<double>(), 40.0);
  EXPECT_DOUBLE_EQ(one["samples"][9][2].get<double>(), 49.0);
  EXPECT_FALSE(one["truncated"].get<bool>());
  const json limited =
      get_json("/api/campaigns/samples?id=hot-pack&version=3&signal=bms.pack_temp_c&limit=5");
  EXPECT_EQ(limited["samples"].size(), 5u);
  EXPECT_TRUE(limited["truncated"].get<bool>());
  // Another version, or a malformed request: not found, bad request.
  auto other = get("/api/campaigns/detail?id=hot-pack&version=4");
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 404);
  for (const std::string bad : {"/api/campaigns/detail?id=hot-pack",
                                "/api/campaigns/detail?"
                                "id=hot-pack&version=x",
                                "/api/campaigns/samples?id=hot-pack&version=3"}) {
    auto res = get(bad);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400) << bad;
  }
}

TEST_F(WebPages, CampaignCsvNeutralisesFormulaCellsAndKeepsNumbers) {
  auto res =
      get("/api/campaigns/samples.csv?id=" + pages_pct(kPagesHostileCampaign) + "&version=1");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "text/csv; charset=utf-8");
  EXPECT_EQ(res->get_header_value("Content-Disposition"),
            "attachment; filename=\"campaign-samples.csv\"");
  // The id and the text start with '=': each gets a leading ' and is quoted (the id's quotes
  // doubled), so a spreadsheet shows text and runs nothing.
  EXPECT_NE(res->body.find("\"'=HYPERLINK(\"\"http://evil\"\")\",1,ride-bike,mc.model,"),
            std::string::npos)
      << res->body;
  EXPECT_NE(res->body.find(",\"'=cmd|' /C calc'!A0\",false,"), std::string::npos) << res->body;
  // Numbers stay numbers, a negative one too (the rule is for text cells).
  auto hot =
      get("/api/campaigns/samples.csv?id=hot-pack&version=3&vehicle=" + pages_pct(kPagesHostileId));
  ASSERT_TRUE(hot);
  EXPECT_NE(hot->body.find(",bms.pack_temp_c," + std::to_string(t_ - 30'000'000) + ",-5.5,,false,"),
            std::string::npos)
      << hot->body;
  // The vehicle id cell starts with '<': plain text, only quoted where CSV needs it.
  EXPECT_NE(hot->body.find("hot-pack,3,<script>window.__xss=1</script>,"), std::string::npos);
}

TEST_F(WebPages, RidePlotHasTheRideSamplesThinnedToTheBound) {
  const json ride = get_json("/api/rides?vehicle=ride-bike&ride=ride-1");
  EXPECT_EQ(ride["fields"], json({"t_us", "speed_kmh", "power_w", "soc_pct", "lat", "lon"}));
  ASSERT_EQ(ride["samples"].size(), static_cast<std::size_t>(kPagesRideSamples));
  EXPECT_EQ(ride["samples_in_ride"], kPagesRideSamples);
  EXPECT_DOUBLE_EQ(ride["samples"][3][1].get<double>(), 11.5);  // (100 + 3 * 5) / 10 km/h
  EXPECT_EQ(ride["samples"][3][2], 230);
  EXPECT_EQ(ride["samples"][29][3], 88);
  EXPECT_NEAR(ride["samples"][29][4].get<double>(), 48.1029, 1e-6);
  // A hostile ride id of a hostile vehicle is found by its strings (query parameters).
  const json hostile = get_json("/api/rides?vehicle=" + pages_pct(kPagesHostileId) +
                                "&ride=" + pages_pct(kPagesHostileRide));
  EXPECT_EQ(hostile["ride"]["ride_id"], kPagesHostileRide);
  auto missing = get("/api/rides?vehicle=ride-bike&ride=nope");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);

  // A long ride: at most kMaxRideSamples (2000) points, the ride's last sample among them.
  stack_->insert_vehicle({.id = "long-bike", .lat = 48.0, .lon = 11.0});
  stack_->rows(
      "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
      "sampled_at_us, speed_dkmh) SELECT 'long-bike', 's', i, i, 1000000 + i * 1000, i % 300 "
      "FROM generate_series(0, 4999) i");
  stack_->rows(
      "INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
      "ride_id, started_at_us, ended_at_us) VALUES ('long-bike', 's', 9000, 1, '0.1.0', 'long', "
      "1000000, 5999000)");
  const json long_ride = get_json("/api/rides?vehicle=long-bike&ride=long");
  EXPECT_EQ(long_ride["samples_in_ride"], 5000);
  EXPECT_LE(long_ride["samples"].size(), 2000u);
  EXPECT_GE(long_ride["samples"].size(), 1600u);
  EXPECT_EQ(long_ride["samples"].back()[0], 5999000);
}

TEST_F(WebPages, VehiclePageSaysTheSpeedLimitInForceAndWhy) {
  const json v = get_json("/api/vehicles/ride-bike");
  const json& sl = v["speed_limit"];
  EXPECT_DOUBLE_EQ(sl["in_force_kmh"].get<double>(), 12.0);
  ASSERT_TRUE(sl["operator_cap"].is_object()) << sl.dump();
  EXPECT_EQ(sl["operator_cap"]["operator"], "olga");
  EXPECT_EQ(sl["operator_cap"]["command"], "speed_limit 20 km/h");
  EXPECT_EQ(sl["operator_cap"]["limit_in_force"],
            "capped at 20; 12 in force inside 'Old <b>Town</b>'");
  // Only the zone it is still in (Harbour was left).
  ASSERT_EQ(sl["slow_zones"].size(), 1u) << sl.dump();
  EXPECT_EQ(sl["slow_zones"][0]["zone_name"], "Old <b>Town</b>");
  EXPECT_EQ(sl["slow_zones"][0]["limit_kmh"], 12);
  // A bike with none of it (its own: ctest runs each test of this suite in its own process).
  stack_->insert_vehicle({.id = "plain-bike", .lat = 48.0, .lon = 11.0});
  const json plain = get_json("/api/vehicles/plain-bike")["speed_limit"];
  EXPECT_TRUE(plain["in_force_kmh"].is_null());
  EXPECT_TRUE(plain["operator_cap"].is_null());
  EXPECT_TRUE(plain["slow_zones"].empty());
}

TEST_F(WebPages, FleetListIsCachedWithAnEtagCompactGzippedAndRebuiltAfterAChange) {
  auto full = get("/api/fleet");
  ASSERT_TRUE(full);
  ASSERT_EQ(full->status, 200);
  const std::string etag = full->get_header_value("ETag");
  ASSERT_EQ(etag.rfind("\"f-", 0), 0u) << etag;
  auto again = get("/api/fleet", {{"If-None-Match", etag}});
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 304);
  EXPECT_TRUE(again->body.empty());
  EXPECT_EQ(again->get_header_value("ETag"), etag);

  // The compact view: the same vehicles and values, arrays in the order of `fields`.
  auto compact = get("/api/fleet?view=compact", {{"Accept-Encoding", "gzip"}});
  ASSERT_TRUE(compact);
  ASSERT_EQ(compact->status, 200);
  EXPECT_EQ(compact->get_header_value("Content-Encoding"), "gzip");  // (the client inflated it)
  EXPECT_EQ(compact->get_header_value("Cache-Control"), "no-store");
  const json c = json::parse(compact->body);
  const json f = json::parse(full->body)["vehicles"];
  ASSERT_EQ(c["vehicles"].size(), f.size());
  EXPECT_EQ(c["fields"], json({"id", "lat", "lon", "state", "soc_pct", "speed_kmh", "last_seen_us",
                               "locks", "alarms_active", "alarms_unacked"}));
  for (std::size_t i = 0; i < f.size(); ++i) {
    EXPECT_EQ(c["vehicles"][i][0], f[i]["id"]);
    EXPECT_EQ(c["vehicles"][i][3], f[i]["state"]);
    EXPECT_EQ(c["vehicles"][i][4], f[i]["soc_pct"]);
  }
  EXPECT_LT(compact->body.size(), full->body.size());
  auto bad = get("/api/fleet?view=everything");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);

  // A new vehicle: the change feed (or the TTL) invalidates the list, the ETag changes.
  stack_->insert_vehicle({.id = "new-bike", .lat = 48.2, .lon = 11.6});
  std::string body;
  EXPECT_TRUE(wait_until(
      [&] {
        auto r = get("/api/fleet", {{"If-None-Match", etag}});
        if (r && r->status == 200) body = r->body;
        return r && r->status == 200;
      },
      10s, 50ms));
  EXPECT_NE(body.find("\"new-bike\""), std::string::npos);
}

// The pages in a real browser: the vehicle page of a bike whose id and ride id hold markup
// draws the ride's track and its plot and runs nothing; the campaign page lists, plots and
// tabulates; a viewer reads it all.
TEST_F(WebPages, BrowserDrawsTheRideTrackPlotAndCampaignPage) {
  const json spec = {{"url", stack_->url()},
                     {"name", "vera"},
                     {"password", "viewer-password"},
                     {"screenshots", stack_->dir().string()},
                     {"vehicle", kPagesHostileId},
                     {"ride", kPagesHostileRide},
                     {"ride_samples", kPagesRideSamples},
                     {"limit_vehicle", "ride-bike"},
                     {"campaign", "hot-pack"},
                     {"campaign_version", 3},
                     {"hostile_campaign", kPagesHostileCampaign}};
  const auto out = stack_->dir() / "browser-pages.log";
  const int rc =
      run_for_exit_code({std::string(FLEETGW_WEB_TEST_DIR) + "/browser/console-browser.sh",
                         "--script", "console_pages_test.mjs", spec.dump()},
                        out);
  if (rc == 77) GTEST_SKIP() << read_text_file(out);
  ASSERT_EQ(rc, 0) << read_text_file(out) << "\nserver:\n" << stack_->log();
}

}  // namespace
}  // namespace fleetgw::testing
