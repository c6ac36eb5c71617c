// Issue 28's "Done when", in one browser session over the real stack: Debian's chromium
// (puppeteer-core) against fleetgw-serve over PostgreSQL, a real mosquitto and a real
// `fleetgw run` on a simulated bike trusting only the fleet's root key. An operator sees the
// fleet on the map, locks the bike with a click (`succeeded`), sees a theft alarm arrive and
// acknowledges it; an admin publishes a zone (drawn on the map) and uploads the root's
// revocation list of the console's delegation; the bike then refuses the operator's next
// command as `revoked`, shown in the console (browser/console_story_test.mjs says what each
// step checks). FLEETGW_DOC_SCREENSHOTS=DIR also writes the screenshots docs/console.md shows.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "tests/support/gateway_config.h"
#include "tests/support/process.h"
#include "tests/support/wait.h"
#include "tests/web/web_command_e2e.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Rows = std::vector<std::vector<std::string>>;

TEST(WebStory, OperatorAndAdminWalkTheWholeConsoleStoryInABrowser) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  CommandRig rig("story-bike", RigDelegation{.actions = {"lock", "unlock", "zones"},
                                             .vehicle_ids = {"story-bike"},
                                             .groups = {}});
  ASSERT_EQ(rig.stack->add_operator("ada", "admin", "admin-password"), 0);
  rig.stack->insert_vehicle({.id = "bike-0002", .lat = 48.139, .lon = 11.583});
  rig.stack->insert_vehicle({.id = "bike-0003", .lat = 48.133, .lon = 11.570, .soc_pct = 12});
  const fs::path dir = rig.dir.path();

  // What the admin uploads: the root's list revoking the console's delegation (serial 7),
  // signed offline by the real tool, and a no-parking zone between the bikes (on no bike).
  const fs::path list = dir / "rev-1.pb";
  run_program({FLEETGW_BINARY, "keys", "revoke", "--root", (dir / "root-1.pem").string(),
               "--root-id", "root-1", "--version", "1", "--serial", "7", "--out", list.string()},
              dir / "revoke.log");
  const json zone = {
      {"type", "FeatureCollection"},
      {"features",
       {{{"type", "Feature"},
         {"properties", {{"id", "station-square"}, {"kind", "no_parking"}, {"name", "Station"}}},
         {"geometry",
          {{"type", "Polygon"},
           {"coordinates",
            {{{11.577, 48.1340},
              {11.580, 48.1340},
              {11.580, 48.1360},
              {11.577, 48.1360},
              {11.577, 48.1340}}}}}}}}}};
  const fs::path zones = dir / "zones.geojson";
  std::ofstream(zones) << zone.dump(1);

  // The theft alarm arrives while the operator watches the feed, from a real bike through the
  // real ingest: the script asks for it by creating this file, and a second `fleetgw run`
  // (config/scenarios/theft.toml: parked and locked, then ridden away) starts; its
  // UNAUTHORISED_MOVEMENT alarm goes through mosquitto to fleetgw-ingest into PostgreSQL, and
  // the console's feed shows it. The thief's fleet has a topic prefix of its own, which the
  // ingest alone reads: story-bike's own state stays the one the map step placed.
  ChildProcess ingest(
      {FLEETGW_INGEST_BINARY, "--broker", rig.broker.uri(), "--client-id", "story-ingest",
       "--topic-prefix", "street/v1", "--pg", rig.stack->conninfo(), "--batch-delay-ms", "100"},
      dir / "ingest.log");
  ASSERT_TRUE(
      wait_until([&] { return !ingest.running() || ingest.log_contains("subscribed to"); }, 30s))
      << ingest.log();
  ASSERT_TRUE(ingest.running()) << ingest.log();
  GatewayConfig thief("thief-bike", dir / "thief.db");
  thief.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/theft.toml", 10);
  thief.mqtt(rig.broker.uri()).set_string("mqtt", "topic_prefix", "street/v1");
  const fs::path thief_config = thief.write(dir / "thief.toml");
  std::unique_ptr<GatewayProcess> thief_bike;
  std::string thief_log_text = "(not started)";
  const fs::path want_alarm = dir / "want-alarm";
  std::atomic<bool> done{false};
  std::atomic<bool> thief_started{false};
  std::thread alarm([&] {
    if (wait_until([&] { return done.load() || fs::exists(want_alarm); }, 90s, 20ms) &&
        !done.load()) {
      thief_bike = std::make_unique<GatewayProcess>(FLEETGW_BINARY, thief_config,
                                                    std::vector<std::string>{"--duration", "600"});
      thief_started = true;
      // Its part is played once the alarm is acknowledged: stopped then, so its telemetry
      // does not keep re-rendering the pages of the steps after.
      wait_until(
          [&] {
            return done.load() || !rig.stack
                                       ->rows(
                                           "SELECT 1 FROM console_alarm_acks WHERE vehicle_id = "
                                           "'thief-bike'")
                                       .empty();
          },
          90s, 50ms);
      thief_log_text = thief_bike->log();
      thief_bike->stop(10s);
    }
  });
  const char* doc_dir = std::getenv("FLEETGW_DOC_SCREENSHOTS");
  const json spec = {{"url", rig.stack->url()},
                     {"operator", {{"name", "olga"}, {"password", "operator-password"}}},
                     {"admin", {{"name", "ada"}, {"password", "admin-password"}}},
                     {"vehicle", "story-bike"},
                     {"vehicles", {"story-bike", "bike-0002", "bike-0003"}},
                     {"revocation_file", list.string()},
                     {"zones_file", zones.string()},
                     {"zone", {{"id", "station-square"}}},
                     {"want_alarm", want_alarm.string()},
                     {"alarm_vehicle", "thief-bike"},
                     {"screenshots", doc_dir != nullptr ? std::string(doc_dir) : dir.string()}};
  const auto out = dir / "browser-story.log";
  const int rc =
      run_for_exit_code({std::string(FLEETGW_WEB_TEST_DIR) + "/browser/console-browser.sh",
                         "--script", "console_story_test.mjs", spec.dump()},
                        out);
  done = true;
  alarm.join();
  const std::string& thief_log = thief_log_text;
  if (rc == 77) GTEST_SKIP() << read_text_file(out);
  ASSERT_EQ(rc, 0) << read_text_file(out) << "\n"
                   << rig.logs() << "\n--- thief-bike:\n"
                   << thief_log << "\n--- ingest:\n"
                   << ingest.log();
  EXPECT_TRUE(thief_started.load());
  // The alarm the operator acknowledged is the bike's own, as the ingest wrote it.
  EXPECT_EQ(rig.stack->rows("SELECT vehicle_id, kind, transition FROM alarms WHERE vehicle_id = "
                            "'thief-bike' ORDER BY sequence LIMIT 1"),
            (Rows{{"thief-bike", "ALARM_KIND_UNAUTHORISED_MOVEMENT", "ALARM_TRANSITION_RAISED"}}));
  std::cout << read_text_file(out);

  // The database agrees with what the browser showed: the lock by olga succeeded, the next one
  // was refused by the bike as revoked; the alarm acknowledged by olga; the zone bundle and
  // the list published by ada, each audited.
  const Rows sent = rig.stack->rows(
      "SELECT action, operator, result, split_part(reason, ':', 1) FROM console_commands "
      "ORDER BY issued_at_us");
  // (A lock racing the list to the bike may still succeed: the script then clicks again.)
  ASSERT_GE(sent.size(), 2u);
  EXPECT_EQ(sent.front(), (std::vector<std::string>{"lock", "olga", "succeeded", ""}));
  EXPECT_EQ(sent.back(), (std::vector<std::string>{"lock", "olga", "rejected", "revoked"}))
      << rig.logs();
  EXPECT_EQ(rig.stack->rows("SELECT vehicle_id, acked_by FROM console_alarm_acks"),
            (Rows{{"thief-bike", "olga"}}));
  EXPECT_EQ(rig.stack->rows("SELECT published_by FROM zone_bundles WHERE vehicle_id = ''"),
            (Rows{{"ada"}}));
  EXPECT_EQ(rig.stack->rows("SELECT operator, action, result FROM console_audit WHERE action IN "
                            "('zones_publish', 'revocations_publish', 'alarm_ack') ORDER BY id"),
            (Rows{{"olga", "alarm_ack", "ok"},
                  {"ada", "zones_publish", "ok"},
                  {"ada", "revocations_publish", "ok"}}));
}

}  // namespace
}  // namespace fleetgw::testing
