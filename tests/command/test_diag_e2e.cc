// Remote diagnostics end to end (issue 29's "Done when"): a technician reads a bike's MC
// lifetime record remotely -- the real `fleetgw command --diag` -> a real mosquitto -> the real
// `fleetgw run` on the simulated bike -> the read on its bus -> the decoded record in the
// result -> the tool's JSON line; then the same record again from the gateway's capture
// without a bus request, and the tool's usage errors.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "gateway/command/ed25519.h"
#include "tests/runtime/service_process.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/source_dir.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace fleetgw::command::testing {
namespace {

using namespace std::chrono_literals;

using ::fleetgw::testing::read_text_file;
struct DiagE2e {
  DiagE2e() {
    broker.start();
    fleetgw::testing::service_config(
        "rt-diag", dir.path(),
        fleetgw::testing::source_dir() / "config" / "scenarios" / "parked.toml", 1, broker.uri(),
        "tech", key.public_key().base64())
        .write(dir.path() / "fleetgw.toml");
    std::ofstream(dir.path() / "tech.pem") << key.pem();
    service.emplace(FLEETGW_BIN, dir.path() / "fleetgw.toml", dir.path() / "service.log");
    ready = fleetgw::testing::wait_until([&] { return service->log_contains("uplink: connected"); },
                                         30s);
  }

  struct Run {
    int exit_code = -1;
    nlohmann::json result;
    std::string err;
  };
  Run tool(const std::vector<std::string>& args) {
    std::vector<std::string> argv{FLEETGW_BIN, "command",    "--vehicle",
                                  "rt-diag",   "--key",      (dir.path() / "tech.pem").string(),
                                  "--broker",  broker.uri(), "--timeout-s",
                                  "10"};
    argv.insert(argv.end(), args.begin(), args.end());
    const auto out = dir.path() / ("diag-" + std::to_string(++runs) + ".out");
    const auto err = dir.path() / ("diag-" + std::to_string(runs) + ".err");
    Run r;
    r.exit_code = fleetgw::testing::run_for_exit_code(argv, out, err);
    r.err = read_text_file(err);
    const std::string text = read_text_file(out);
    if (!text.empty()) r.result = nlohmann::json::parse(text, nullptr, false);
    return r;
  }
  std::string log() const { return read_text_file(dir.path() / "service.log"); }

  fleetgw::testing::TempDir dir{"fleetgw-diag-e2e"};
  fleetgw::testing::MosquittoBroker broker;
  Ed25519PrivateKey key = Ed25519PrivateKey::generate();
  std::optional<fleetgw::testing::ServiceProcess> service;
  bool ready = false;
  int runs = 0;
};

// The value of signal `name` in the tool's "diagnostic" object (null when absent).
nlohmann::json diag_e2e_value(const nlohmann::json& result, const std::string& name) {
  if (!result.is_object() || !result.contains("diagnostic")) return nullptr;
  for (const auto& m : result["diagnostic"]["messages"]) {
    for (const auto& v : m["values"]) {
      if (v.value("name", std::string()) == name) return v["value"];
    }
  }
  return nullptr;
}

TEST(CommandMqttDiag, ATechnicianReadsTheMcLifetimeRecordRemotely) {
  DiagE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  // The bike boots with the gateway; a read before the MC is up answers node_offline.
  DiagE2e::Run life;
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        life = rig.tool({"--diag", "mc_lifetime"});
        return life.exit_code != 1 ||
               life.result.value("reason", std::string()).rfind("node_offline", 0) != 0;
      },
      20s, 200ms))
      << life.err << rig.log();
  ASSERT_EQ(life.exit_code, 0) << life.err << life.result.dump() << rig.log();
  EXPECT_EQ(life.result["result"], "succeeded");
  const auto& d = life.result["diagnostic"];
  EXPECT_EQ(d["block"], "mc_lifetime");
  EXPECT_EQ(d["node"], "mc");
  EXPECT_EQ(d["source"], "bus");
  ASSERT_EQ(d["messages"].size(), 2u) << d.dump();
  EXPECT_EQ(d["messages"][0]["message"], "mc_lifetime_1");
  EXPECT_EQ(d["messages"][0]["can_id"], "0x715");
  EXPECT_EQ(d["messages"][0]["command"], "0xA230");
  EXPECT_EQ(d["messages"][0]["data"].get<std::string>().size(), 96u);  // 48 bytes in hex
  EXPECT_EQ(d["messages"][1]["message"], "mc_lifetime_2");
  const auto power_ons = diag_e2e_value(life.result, "mc.lifetime_1.power_on_count");
  ASSERT_TRUE(power_ons.is_number()) << d.dump();
  EXPECT_GE(power_ons.get<double>(), 400);
  EXPECT_TRUE(diag_e2e_value(life.result, "mc.lifetime_1.motor_temp_max_c").is_number());
  EXPECT_TRUE(diag_e2e_value(life.result, "mc.lifetime_2.mos_short_count").is_number());

  // The same record again, from what the gateway captured: no bus request.
  const auto captured = rig.tool({"--diag", "mc_lifetime", "--captured"});
  ASSERT_EQ(captured.exit_code, 0) << captured.err << captured.result.dump();
  EXPECT_EQ(captured.result["diagnostic"]["source"], "captured");
  EXPECT_EQ(captured.result["diagnostic"]["requests_sent"], 0);
  EXPECT_EQ(captured.result["diagnostic"]["messages"][0]["data"], d["messages"][0]["data"]);

  // Another block through the same path: the BMS's cells.
  const auto cells = rig.tool({"--diag", "bms_cells"});
  EXPECT_EQ(cells.exit_code, 0) << cells.err << cells.result.dump();
  EXPECT_TRUE(diag_e2e_value(cells.result, "bms.cells.cells_mv[0]").is_number())
      << cells.result.dump();

  // Usage errors: exit 2, nothing sent.
  EXPECT_EQ(rig.tool({"--diag", "mc_everything"}).exit_code, 2);
  EXPECT_EQ(rig.tool({"--diag", "mc_settings", "--captured"}).exit_code, 2);
  EXPECT_EQ(rig.tool({"--diag", "lock_model"}).exit_code, 2);
  EXPECT_EQ(rig.tool({"--diag", "mc_settings", "--clear-trip"}).exit_code, 2);
  EXPECT_EQ(rig.service->stop(), 0) << rig.log();
}

}  // namespace
}  // namespace fleetgw::command::testing
