// MC actions end to end (issue 13): the real `fleetgw command` -> a real mosquitto -> the real
// `fleetgw run` (child process) on the simulated bike -> the settings read, the 0x3408 write
// and the read-back on its bus -> the result over MQTT -> the tool's JSON line and exit code.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>

#include <algorithm>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/ed25519.h"
#include "tests/runtime/service_process.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/source_dir.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace fleetgw::command::testing {
namespace {

using namespace std::chrono_literals;

std::filesystem::path mc_e2e_scenario(const std::string& name = "parked") {
  return fleetgw::testing::source_dir() / "config" / "scenarios" / (name + ".toml");
}

std::string mc_e2e_read(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct McE2e {
  // Default: the parked bike at speed 1 (bus time = wall time: the round trip is what an
  // operator would see). `scenario_text`, when given, is the scenario itself (written to the
  // rig's directory) instead of config/scenarios/<scenario>.toml.
  explicit McE2e(const std::string& scenario = "parked", double speed = 1,
                 const std::string& scenario_text = {}) {
    broker.start();
    std::filesystem::path scenario_file = mc_e2e_scenario(scenario);
    if (!scenario_text.empty()) {
      scenario_file = dir.path() / (scenario + ".toml");
      std::ofstream(scenario_file) << scenario_text;
    }
    // The status socket in the rig's directory, not /run/fleetgw (`fleetgw status` reads it).
    fleetgw::testing::service_config("rt-mc", dir.path(), scenario_file, speed, broker.uri(), "ops",
                                     key.public_key().base64())
        .write(dir.path() / "fleetgw.toml");
    std::ofstream(dir.path() / "ops.pem") << key.pem();
    service.emplace(FLEETGW_BIN, dir.path() / "fleetgw.toml", dir.path() / "service.log");
    ready = fleetgw::testing::wait_until([&] { return service->log_contains("uplink: connected"); },
                                         30s);
  }

  struct Run {
    int exit_code = -1;
    nlohmann::json result;  // the tool's JSON line, null when none
    std::string err;
  };
  // `fleetgw command --vehicle rt-mc <args> ...` as an operator types it.
  Run tool(const std::vector<std::string>& args) {
    std::vector<std::string> argv{FLEETGW_BIN, "command",    "--vehicle",
                                  "rt-mc",     "--key",      (dir.path() / "ops.pem").string(),
                                  "--broker",  broker.uri(), "--timeout-s",
                                  "20"};
    argv.insert(argv.end(), args.begin(), args.end());
    const auto out = dir.path() / ("tool-" + std::to_string(++runs) + ".out");
    const auto err = dir.path() / ("tool-" + std::to_string(runs) + ".err");
    Run r;
    r.exit_code = fleetgw::testing::run_for_exit_code(argv, out, err);
    r.err = mc_e2e_read(err);
    const std::string text = mc_e2e_read(out);
    if (!text.empty()) r.result = nlohmann::json::parse(text, nullptr, false);
    return r;
  }
  // Polls until the gateway has heard the MC (an early command is refused mc_offline).
  Run until_mc_known(const std::vector<std::string>& args) {
    Run r;
    fleetgw::testing::wait_until(
        [&] {
          r = tool(args);
          const std::string reason =
              r.result.is_object() ? r.result.value("reason", std::string()) : std::string();
          return reason.rfind("mc_offline", 0) != 0 && reason.rfind("mc_state_unknown", 0) != 0;
        },
        30s, 200ms);
    return r;
  }
  std::string log() const { return mc_e2e_read(dir.path() / "service.log"); }
  // `fleetgw status --format json` of the running service (null when it does not answer).
  nlohmann::json status() {
    const auto out = dir.path() / ("status-" + std::to_string(++runs) + ".out");
    fleetgw::testing::run_for_exit_code(
        {FLEETGW_BIN, "status", "--config", (dir.path() / "fleetgw.toml").string(), "--format",
         "json"},
        out, dir.path() / "status.err");
    return nlohmann::json::parse(mc_e2e_read(out), nullptr, false);
  }
  // The assist level `fleetgw status` shows ("" until heard).
  std::string status_assist() {
    const auto doc = status();
    if (!doc.is_object() || !doc.contains("vehicle") || !doc["vehicle"]["assist"].is_string())
      return {};
    return doc["vehicle"]["assist"].get<std::string>();
  }

  fleetgw::testing::TempDir dir{"fleetgw-mc-e2e"};
  fleetgw::testing::MosquittoBroker broker;
  Ed25519PrivateKey key = Ed25519PrivateKey::generate();
  std::optional<fleetgw::testing::ServiceProcess> service;
  bool ready = false;
  int runs = 0;
};

TEST(CommandMqttMc, SpeedLimitIsConfirmedEndToEndThroughFleetgwRun) {
  McE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  const auto first = rig.until_mc_known({"--speed-limit", "15"});
  ASSERT_TRUE(first.result.is_object()) << first.err << rig.log();
  EXPECT_EQ(first.exit_code, 0) << first.err;
  EXPECT_EQ(first.result["result"], "succeeded") << first.result.dump();
  ASSERT_TRUE(first.result.contains("mc")) << first.result.dump();
  EXPECT_EQ(first.result["mc"]["action"], "speed_limit");
  EXPECT_EQ(first.result["mc"]["speed_limit_kmh"], 15);
  EXPECT_EQ(first.result["mc"]["factory_speed_limit_kmh"], 25);
  EXPECT_EQ(first.result["mc"]["writes_sent"], 1);
  EXPECT_TRUE(first.result["stored"].get<bool>());

  // Round trips (tool publish -> result), alternating limits so each one really writes.
  std::vector<std::int64_t> rt;
  for (int i = 0; i < 5; ++i) {
    const auto r = rig.tool({"--speed-limit", i % 2 == 0 ? "20" : "15"});
    ASSERT_EQ(r.exit_code, 0) << r.err << r.result.dump();
    EXPECT_EQ(r.result["mc"]["speed_limit_kmh"], i % 2 == 0 ? 20 : 15);
    rt.push_back(r.result["round_trip_ms"].get<std::int64_t>());
  }
  std::sort(rt.begin(), rt.end());
  RecordProperty("speed_limit_round_trip_median_ms", std::to_string(rt[rt.size() / 2]));
  std::cout << "speed-limit round trip through fleetgw run: median " << rt[rt.size() / 2]
            << " ms, max " << rt.back() << " ms\n";

  // Outside the MC's range: rejected, exit 1, nothing written (the MC keeps 15).
  const auto high = rig.tool({"--speed-limit", "40"});
  EXPECT_EQ(high.exit_code, 1) << high.err;
  EXPECT_EQ(high.result["result"], "rejected");
  EXPECT_EQ(high.result["reason"].get<std::string>().rfind("out_of_range", 0), 0u)
      << high.result.dump();
  const auto check = rig.tool({"--speed-limit", "15"});
  EXPECT_EQ(check.exit_code, 0);
  EXPECT_EQ(check.result["mc"]["speed_limit_kmh"], 15);

  // The other actions through the same path.
  const auto lights = rig.tool({"--lights", "on"});
  EXPECT_EQ(lights.exit_code, 0) << lights.err << lights.result.dump();
  EXPECT_EQ(lights.result["mc"]["headlight_on"], true);
  const auto assist = rig.tool({"--assist", "eco"});
  EXPECT_EQ(assist.exit_code, 0) << assist.err << assist.result.dump();
  EXPECT_EQ(assist.result["mc"]["assist_level"], "eco");
  EXPECT_EQ(rig.service->stop(), 0) << rig.log();
}

TEST(CommandMqttMc, ClearTripIsConfirmedAndPowerOffRefusedWhileRiding) {
  McE2e rig("ride", 20);  // 20x: the trip counter passes 500 m within seconds
  ASSERT_TRUE(rig.ready) << rig.log();
  // Riding: power off is refused by the motion interlock and nothing is shut down.
  const auto refused = rig.until_mc_known({"--power-off"});
  ASSERT_TRUE(refused.result.is_object()) << refused.err << rig.log();
  EXPECT_EQ(refused.exit_code, 1) << refused.err;
  EXPECT_EQ(refused.result["result"], "rejected") << refused.result.dump();
  EXPECT_EQ(refused.result["reason"].get<std::string>().rfind("interlock_moving", 0), 0u)
      << refused.result.dump();
  // Until the trip counter has passed ~500 m: 100 s of telemetry at 20 km/h (after 40 s at 8).
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        const std::string n = fleetgw::testing::query_text(
            rig.dir.path() / "fleetgw.db", "SELECT count(*) FROM telemetry WHERE speed_kmh > 15");
        return !n.empty() && std::stoi(n) >= 100;
      },
      60s, 200ms))
      << rig.log();
  // Clear trip is confirmed only by the MC's running data showing the trip back near zero.
  const auto cleared = rig.tool({"--clear-trip"});
  EXPECT_EQ(cleared.exit_code, 0) << cleared.err << cleared.result.dump();
  EXPECT_EQ(cleared.result["result"], "succeeded") << cleared.result.dump();
  EXPECT_EQ(cleared.result["mc"]["action"], "clear_trip");
  EXPECT_LT(cleared.result["mc"].value("trip_m", 999999), 100) << cleared.result.dump();
  EXPECT_TRUE(rig.service->running()) << rig.log();
}

TEST(CommandMqttMc, PowerOffOfAParkedBikeIsConfirmedByTheReadyReplies) {
  McE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  const auto off = rig.until_mc_known({"--power-off"});
  ASSERT_TRUE(off.result.is_object()) << off.err << rig.log();
  EXPECT_EQ(off.exit_code, 0) << off.err << off.result.dump();
  EXPECT_EQ(off.result["result"], "succeeded") << off.result.dump();
  EXPECT_EQ(off.result["mc"]["action"], "power_off");
  EXPECT_EQ(off.result["mc"]["mc_ready"], true) << off.result.dump();
  EXPECT_EQ(off.result["mc"]["obc_ready"], true) << off.result.dump();
}

TEST(CommandMqttMc, UsageErrorsExitTwoWithoutPublishing) {
  McE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"--speed-limit", "15", "--clear-trip"},  // two actions
           {"--speed-limit", "300"},                 // beyond one byte
           {"--lights", "dim"},                      // not on/off
           {"--assist", "Eco; rm"},                  // not a level name
           {"--lock", "seat"},                       // --lock without --action
           {},                                       // no action at all
       }) {
    const auto r = rig.tool(args);
    std::string line;
    for (const auto& a : args) line += a + " ";
    EXPECT_EQ(r.exit_code, 2) << line << r.err;
    EXPECT_TRUE(r.result.is_null()) << line;
  }
  EXPECT_EQ(rig.log().find("command received"), std::string::npos) << rig.log();
}

// The retained last-known state on fleet/v1/rt-mc/state as a dashboard sees it: the assist level
// there comes from the MC's running data through the service's state, not from the result.
class StateWatch {
 public:
  explicit StateWatch(const std::string& uri) : client_(uri, "mc-e2e-state-watch") {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      v1::Envelope e;
      if (!e.ParseFromString(m->get_payload()) || !e.has_state()) return;
      std::lock_guard lock(mu_);
      last_ = e.state();
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/rt-mc/state", 1)->wait();
  }
  ~StateWatch() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {
    }
  }
  StateWatch(const StateWatch&) = delete;
  StateWatch& operator=(const StateWatch&) = delete;
  std::string assist_name() {
    std::lock_guard lock(mu_);
    return last_ ? last_->assist_name() : std::string();
  }

 private:
  mqtt::async_client client_;
  std::mutex mu_;
  std::optional<v1::VehicleState> last_;
};

// A bike ridden at 18 km/h from the start, unlocked, NORM and the headlight on, so that every
// command below changes something the MC then has to show.
constexpr const char* kRidingScenario =
    "[scenario]\nname = \"assist-e2e\"\nduration_s = 1200\n[bike]\nseed = 13\nsoc_pct = 80\n"
    "assist = \"norm\"\nheadlight = true\nlocks_locked = false\n[[ride]]\nduration_s = 1200\n"
    "speed_kmh = 18\n";

TEST(CommandMqttMc, AssistAndHeadlightAreConfirmedOnARidingBike) {
  McE2e rig("assist-e2e", 1, kRidingScenario);
  ASSERT_TRUE(rig.ready) << rig.log();
  StateWatch state(rig.broker.uri());
  // Riding, and the service shows the scenario's level before anything is commanded.
  nlohmann::json doc;
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        doc = rig.status();
        if (!doc.is_object() || !doc.contains("vehicle")) return false;
        const auto& v = doc["vehicle"];
        return v["speed_kmh"].is_number() && v["speed_kmh"].get<double>() > 5 &&
               v["assist"] == "norm";
      },
      30s, 200ms))
      << doc.dump() << rig.log();

  const auto sport = rig.until_mc_known({"--assist", "sport"});
  ASSERT_TRUE(sport.result.is_object()) << sport.err << rig.log();
  EXPECT_EQ(sport.exit_code, 0) << sport.err << sport.result.dump();
  EXPECT_EQ(sport.result["result"], "succeeded") << sport.result.dump();
  EXPECT_EQ(sport.result["mc"]["action"], "assist_level");
  EXPECT_EQ(sport.result["mc"]["assist_level"], "sport") << sport.result.dump();
  // The other half of 0x3002 is kept: the headlight stays on.
  EXPECT_EQ(sport.result["mc"]["headlight_on"], true) << sport.result.dump();
  EXPECT_EQ(sport.result["mc"]["writes_sent"], 1);
  EXPECT_TRUE(sport.result["stored"].get<bool>());
  // Independently of the result: `fleetgw status` and the retained state show the new level.
  EXPECT_TRUE(
      fleetgw::testing::wait_until([&] { return rig.status_assist() == "sport"; }, 10s, 200ms))
      << rig.status().dump();
  EXPECT_TRUE(
      fleetgw::testing::wait_until([&] { return state.assist_name() == "sport"; }, 15s, 200ms))
      << "retained state assist: '" << state.assist_name() << "'";

  const auto off = rig.tool({"--lights", "off"});
  EXPECT_EQ(off.exit_code, 0) << off.err << off.result.dump();
  EXPECT_EQ(off.result["result"], "succeeded") << off.result.dump();
  EXPECT_EQ(off.result["mc"]["action"], "headlight");
  EXPECT_EQ(off.result["mc"]["headlight_on"], false) << off.result.dump();
  EXPECT_EQ(off.result["mc"]["assist_level"], "sport") << off.result.dump();  // kept

  const auto on = rig.tool({"--lights", "on"});
  EXPECT_EQ(on.exit_code, 0) << on.err << on.result.dump();
  EXPECT_EQ(on.result["result"], "succeeded") << on.result.dump();
  EXPECT_EQ(on.result["mc"]["headlight_on"], true) << on.result.dump();
  EXPECT_EQ(on.result["mc"]["assist_level"], "sport") << on.result.dump();

  // A well-formed name the gateway has not configured: the tool sends it (names are the
  // gateway's), the gateway refuses it before writing, and the MC keeps SPORT.
  const auto warp = rig.tool({"--assist", "warp"});
  EXPECT_EQ(warp.exit_code, 1) << warp.err << warp.result.dump();
  EXPECT_EQ(warp.result["result"], "rejected") << warp.result.dump();
  EXPECT_EQ(warp.result["reason"].get<std::string>().rfind("unknown_assist_level", 0), 0u)
      << warp.result.dump();
  const auto still = rig.tool({"--lights", "on"});  // confirmed from the MC's running data
  EXPECT_EQ(still.exit_code, 0) << still.err << still.result.dump();
  EXPECT_EQ(still.result["mc"]["assist_level"], "sport") << still.result.dump();
  EXPECT_EQ(rig.status_assist(), "sport");
  // A malformed name is a usage error: exit 2, nothing published.
  const auto bad = rig.tool({"--assist", "Warp"});
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_TRUE(bad.result.is_null()) << bad.result.dump();
  EXPECT_NE(bad.err.find("--assist"), std::string::npos) << bad.err;
  EXPECT_EQ(rig.service->stop(), 0) << rig.log();
}

TEST(CommandMqttMc, AssistAndHeadlightIgnoredByTheMcFail) {
  // The MC answers reads and keeps sending its running data but drops every write.
  McE2e rig("mc-ignores", 1,
            "[scenario]\nname = \"mc-ignores\"\nduration_s = 600\n[bike]\nseed = 99\n"
            "assist = \"eco\"\nheadlight = false\nvehicle_locked = true\nlocks_locked = true\n"
            "mc_ignores_writes = true\n");
  ASSERT_TRUE(rig.ready) << rig.log();
  const auto assist = rig.until_mc_known({"--assist", "sport"});
  ASSERT_TRUE(assist.result.is_object()) << assist.err << rig.log();
  EXPECT_EQ(assist.exit_code, 1) << assist.err << assist.result.dump();
  EXPECT_EQ(assist.result["result"], "failed") << assist.result.dump();
  EXPECT_EQ(assist.result["reason"].get<std::string>().rfind("not_confirmed", 0), 0u)
      << assist.result.dump();
  // Written, unconfirmed, written again (retries = 1), and what the MC still shows.
  EXPECT_EQ(assist.result["mc"]["writes_sent"], 2) << assist.result.dump();
  EXPECT_EQ(assist.result["mc"]["assist_level"], "eco") << assist.result.dump();
  EXPECT_EQ(rig.status_assist(), "eco");

  const auto lights = rig.tool({"--lights", "on"});
  EXPECT_EQ(lights.exit_code, 1) << lights.err << lights.result.dump();
  EXPECT_EQ(lights.result["result"], "failed") << lights.result.dump();
  EXPECT_EQ(lights.result["mc"]["headlight_on"], false) << lights.result.dump();
  EXPECT_EQ(rig.service->stop(), 0) << rig.log();
}

}  // namespace
}  // namespace fleetgw::command::testing
