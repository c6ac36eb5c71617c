// The console in a real browser (issue 28): the real fleetgw-serve over PostgreSQL with rows in
// the ingest's tables, and Debian's chromium driven by puppeteer-core (browser/console_test.mjs
// says what it checks). Skipped only when node, npm or chromium is missing or npm cannot fetch
// puppeteer-core.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <iostream>

#include "tests/web/web_command_e2e.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

TEST(WebBrowser, OperatorSeesTheFleetOnTheMapAndAcknowledgesAnAlarm) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  ServeStack stack;
  ASSERT_EQ(stack.add_operator("olga", "operator", "operator-password"), 0);
  const std::string xss_id = "<script>window.__xss=1</script>";
  const std::vector<VehicleRow> rows = {
      {.id = "west-bike", .lat = 48.100, .lon = 11.500},
      {.id = "east-bike", .lat = 48.104, .lon = 11.520, .mode = "VEHICLE_MODE_RIDING"},
      {.id = "flat-bike", .lat = 48.110, .lon = 11.510, .soc_pct = 9},
      {.id = "gone-bike", .lat = 48.095, .lon = 11.515, .status_online = false},
      {.id = xss_id, .lat = 48.106, .lon = 11.505},
  };
  for (const VehicleRow& v : rows) stack.insert_vehicle(v);
  stack.insert_alarm(xss_id, 3, "ALARM_KIND_UNAUTHORISED_MOVEMENT", "ALARM_TRANSITION_RAISED",
                     now_us(), "<img src=x onerror=\"window.__xss=2\">");
  const nlohmann::json spec = {
      {"url", stack.url()},
      {"name", "olga"},
      {"password", "operator-password"},
      {"screenshots", stack.dir().string()},
      {"xss_id", xss_id},
      {"ack_vehicle", xss_id},
      {"vehicles",
       {{{"id", "west-bike"}, {"lat", 48.100}, {"lon", 11.500}, {"state", "parked"}},
        {{"id", "east-bike"}, {"lat", 48.104}, {"lon", 11.520}, {"state", "riding"}},
        {{"id", "flat-bike"}, {"lat", 48.110}, {"lon", 11.510}, {"state", "low_battery"}},
        {{"id", "gone-bike"}, {"lat", 48.095}, {"lon", 11.515}, {"state", "offline"}},
        {{"id", xss_id}, {"lat", 48.106}, {"lon", 11.505}, {"state", "alarm"}}}}};
  const auto out = stack.dir() / "browser.log";
  const int rc = run_for_exit_code(
      {std::string(FLEETGW_WEB_TEST_DIR) + "/browser/console-browser.sh", spec.dump()}, out);
  if (rc == 77) GTEST_SKIP() << read_text_file(out);
  ASSERT_EQ(rc, 0) << read_text_file(out) << "\nserver:\n" << stack.log();
  // The click went all the way: acknowledged in the database by the operator who clicked.
  EXPECT_EQ(stack.rows("SELECT vehicle_id, acked_by FROM console_alarm_acks"),
            (std::vector<std::vector<std::string>>{{xss_id, "olga"}}));
  EXPECT_EQ(stack.rows("SELECT count(*) FROM console_audit WHERE action = 'alarm_ack' AND "
                       "result = 'ok' AND operator = 'olga'"),
            (std::vector<std::vector<std::string>>{{"1"}}));
}

// The whole command path from a click (issue 28): the operator unlocks and locks a real
// `fleetgw run` bike from its page and sees `succeeded`; the map's screenshot has the bikes'
// colours at their markers; a viewer has no buttons and gets 403; no CSRF token, 403.
TEST(WebBrowser, OperatorLocksARealBikeWithAClickAndAViewerCannot) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  // bench/console-commands.sh asks for more clicks (and reads the times this test prints).
  const char* env = std::getenv("FLEETGW_CONSOLE_CLICKS");
  const int clicks = env != nullptr ? std::max(2, std::atoi(env)) : 2;
  CommandRig rig("click-bike");
  rig.stack->insert_vehicle({.id = "flat-bike", .lat = 48.140, .lon = 11.585, .soc_pct = 9});
  const nlohmann::json spec = {
      {"url", rig.stack->url()},
      {"operator", {{"name", "olga"}, {"password", "operator-password"}}},
      {"viewer", {{"name", "vera"}, {"password", "viewer-password"}}},
      {"vehicle", "click-bike"},
      {"clicks", clicks},
      {"screenshots", rig.stack->dir().string()},
      {"markers",
       {{{"id", "click-bike"}, {"lat", 48.137}, {"lon", 11.575}, {"state", "parked"}},
        {{"id", "flat-bike"}, {"lat", 48.140}, {"lon", 11.585}, {"state", "low_battery"}}}}};
  const auto out = rig.stack->dir() / "browser-command.log";
  const int rc = run_for_exit_code({std::string(FLEETGW_WEB_TEST_DIR) +
                                        "/browser/console-browser.sh",
                                    "--script", "console_command_test.mjs", spec.dump()},
                                   out);
  if (rc == 77) GTEST_SKIP() << read_text_file(out);
  ASSERT_EQ(rc, 0) << read_text_file(out) << "\n" << rig.logs();
  std::cout << read_text_file(out);  // {"click_to_result_ms": [...]}
  // Every click reached the bike as olga's and came back succeeded (unlock, lock, ...); the
  // viewer's and the token-less POSTs were refused before anything was signed.
  const auto sent = rig.stack->rows(
      "SELECT action, operator, result_operator, result FROM console_commands ORDER BY "
      "issued_at_us");
  ASSERT_EQ(sent.size(), static_cast<std::size_t>(clicks));
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_EQ(sent[i], (std::vector<std::string>{i % 2 == 0 ? "unlock" : "lock", "olga", "olga",
                                                 "succeeded"}));
  }
  EXPECT_EQ(rig.stack->rows("SELECT operator, result FROM console_audit WHERE action = "
                            "'command' AND result <> 'published' ORDER BY id"),
            (std::vector<std::vector<std::string>>{{"olga", "refused_csrf"},
                                                   {"vera", "forbidden"}}));
}

}  // namespace
}  // namespace fleetgw::testing
