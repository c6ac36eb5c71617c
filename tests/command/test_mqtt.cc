// The operator tool end to end through a real mosquitto: tool -> broker -> real Uplink -> the
// CommandService -> IotNode -> simulated bike (in real-time lockstep) -> result in the SQLite
// outbox -> Uplink -> broker -> tool. Plus keygen.
#include <sys/stat.h>
#include <functional>

#include <atomic>
#include <future>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "gateway/runtime/store_outbox.h"
#include "gateway/tools/operator/command_tool.h"
#include "gateway/uplink/uplink.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

sim::Scenario live_scenario(sim::Scenario sc = quiet_scenario()) {
  sc.start = wall_now();
  return sc;
}

// The gateway side: the rig's bus follows the wall clock; the uplink delivers commands to the
// service on this (the driving) thread.
class LiveGateway {
 public:
  LiveGateway(const std::string& broker_uri, sim::Scenario sc = quiet_scenario())
      : rig(live_scenario(std::move(sc))), outbox(*rig.store) {
    uplink::UplinkConfig c;
    c.broker_uri = broker_uri;
    c.vehicle_id = kVehicle;
    c.firmware_version = "test";
    c.reconnect_min = 200ms;
    c.reconnect_max = 1000ms;
    link = std::make_unique<uplink::Uplink>(c, outbox);
    // As the pipeline wires it: signatures checked on Paho's thread before queueing.
    link->set_command_authenticator(
        [auth = rig.service->authenticator()](std::string_view payload) {
          auto a = auth({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()});
          return uplink::CommandTriage{a.authenticated, std::move(a.command_id),
                                       std::move(a.command_sha256)};
        });
    link->start(wall_now());
  }
  ~LiveGateway() { link->stop(wall_now(), 2s); }

  void step() {
    const Micros now = wall_now();
    if (now > rig.bus.now()) rig.bus.run_until(now);
    link->poll(now);
    for (const auto& payload : link->take_commands()) {
      if (on_command) {
        on_command(payload);
      } else {
        rig.service->on_payload(payload, now);
      }
    }
    for (const auto& b : link->take_busy_commands()) {
      rig.service->answer_busy(b.command_id, b.command_sha256, now);
    }
    link->wait_for_events(2ms);
  }
  // Replaces the plain hand-over of each command taken from the uplink (a test's attacker).
  std::function<void(std::string_view)> on_command;
  bool run_until_connected(std::chrono::seconds limit) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      step();
      if (link->state() == uplink::UplinkState::kConnected) {
        // Let the cmd subscription complete and the locks be heard.
        const auto settle = std::chrono::steady_clock::now() + 1500ms;
        while (std::chrono::steady_clock::now() < settle) step();
        return true;
      }
    }
    return false;
  }
  template <typename F>
  auto drive_while(std::future<F>& f) {
    while (f.wait_for(0ms) != std::future_status::ready) step();
    return f.get();
  }

  Rig rig;
  runtime::StoreOutbox outbox;
  std::unique_ptr<uplink::Uplink> link;
};

struct ToolRun {
  int exit_code = -1;
  std::string out, err;
};

std::future<ToolRun> launch_tool(CommandToolOptions o) {
  return std::async(std::launch::async, [o]() mutable {
    std::ostringstream out, err;
    o.out = &out;
    o.err = &err;
    ToolRun r;
    r.exit_code = run_command_tool(o);
    r.out = out.str();
    r.err = err.str();
    return r;
  });
}

CommandToolOptions tool_options(const fleetgw::testing::MosquittoBroker& broker,
                                const std::filesystem::path& key, std::string lock,
                                std::string action) {
  CommandToolOptions o;
  o.vehicle = kVehicle;
  o.lock = std::move(lock);
  o.action = std::move(action);
  o.key = key;
  o.key_id = kKeyId;
  o.broker = broker.uri();
  o.timeout = 20s;
  return o;
}

TEST(CommandMqtt, ToolUnlocksAndLocksThroughTheRealBrokerAndUplink) {
  fleetgw::testing::MosquittoBroker broker;
  broker.start();
  LiveGateway gw(broker.uri());
  ASSERT_TRUE(gw.run_until_connected(20s)) << broker.log();
  const auto key_file = gw.rig.dir.path() / "ops.pem";
  gw.rig.key.write_pem(key_file);

  auto f = launch_tool(tool_options(broker, key_file, "seat", "unlock"));
  const ToolRun unlock = gw.drive_while(f);
  EXPECT_EQ(unlock.exit_code, 0) << unlock.out << unlock.err;
  const auto j = nlohmann::json::parse(unlock.out);
  EXPECT_EQ(j["result"], "succeeded");
  EXPECT_EQ(j["final_lock_state_name"], "unlocked");
  EXPECT_EQ(j["vehicle_id"], kVehicle);
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kUnlocked);

  auto g = launch_tool(tool_options(broker, key_file, "seat", "lock"));
  const ToolRun lock = gw.drive_while(g);
  EXPECT_EQ(lock.exit_code, 0) << lock.out << lock.err;
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kLocked);
  EXPECT_EQ(gw.rig.sender.lock_writes(), 2u);
}

TEST(CommandMqtt, ToolExitsNonZeroWhenRejectedOrFailed) {
  fleetgw::testing::MosquittoBroker broker;
  broker.start();
  auto sc = quiet_scenario();
  sim::ScenarioEvent jam;
  jam.action = sim::Action::kJamLock;
  jam.node = motinova::Node::kLock4;  // battery
  sc.events.push_back(jam);
  LiveGateway gw(broker.uri(), sc);
  ASSERT_TRUE(gw.run_until_connected(20s)) << broker.log();

  // Signed with a key the gateway does not trust, under a trusted key id.
  const auto rogue = gw.rig.dir.path() / "rogue.pem";
  Ed25519PrivateKey::generate().write_pem(rogue);
  auto f = launch_tool(tool_options(broker, rogue, "seat", "unlock"));
  const ToolRun rejected = gw.drive_while(f);
  EXPECT_EQ(rejected.exit_code, kExitNotSucceeded) << rejected.out << rejected.err;
  EXPECT_EQ(nlohmann::json::parse(rejected.out)["result"], "rejected");
  EXPECT_NE(rejected.out.find("signature_invalid"), std::string::npos) << rejected.out;
  EXPECT_EQ(gw.rig.sender.lock_writes(), 0u);
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kLocked);

  const auto key_file = gw.rig.dir.path() / "ops.pem";
  gw.rig.key.write_pem(key_file);
  auto g = launch_tool(tool_options(broker, key_file, "battery", "unlock"));
  const ToolRun failed = gw.drive_while(g);
  EXPECT_EQ(failed.exit_code, kExitNotSucceeded) << failed.out << failed.err;
  EXPECT_EQ(nlohmann::json::parse(failed.out)["result"], "failed");
}

TEST(CommandMqtt, ToolPrintsOnlyTheResultBoundToTheCommandItSent) {
  // An attacker who sees the genuine payload on `cmd` gets two forgeries in before it: a copy
  // of its exact command bytes and id with a broken signature, and a different command under
  // the same id. Each is answered `rejected: signature_invalid` under that id, published before
  // the genuine result; the tool must print the genuine `succeeded` only.
  fleetgw::testing::MosquittoBroker broker;
  broker.start();
  LiveGateway gw(broker.uri());
  int forged_first = 0;
  gw.on_command = [&](std::string_view payload) {
    const std::string genuine(payload);
    if (Rig::id_of(genuine) == "cmd-spoofed" && forged_first == 0) {
      for (const auto& forged : {broken_copy(genuine), forged_other(genuine)}) {
        EXPECT_EQ(gw.rig.service->on_payload(forged, gw.rig.bus.now()), Disposition::kRejected);
        ++forged_first;
      }
    }
    gw.rig.service->on_payload(genuine, gw.rig.bus.now());
  };
  ASSERT_TRUE(gw.run_until_connected(20s)) << broker.log();
  const auto key_file = gw.rig.dir.path() / "ops.pem";
  gw.rig.key.write_pem(key_file);

  auto o = tool_options(broker, key_file, "seat", "unlock");
  o.command_id = "cmd-spoofed";
  auto f = launch_tool(o);
  const ToolRun run = gw.drive_while(f);
  EXPECT_EQ(forged_first, 2);
  EXPECT_EQ(run.exit_code, kExitSucceeded) << run.out << run.err;
  EXPECT_EQ(std::count(run.out.begin(), run.out.end(), '\n'), 1) << run.out;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["command_id"], "cmd-spoofed");
  EXPECT_EQ(j["result"], "succeeded");
  EXPECT_EQ(j["stored"], true);
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kUnlocked);
  // The forgeries' answers did reach the tool, and were set aside.
  std::size_t ignored = 0;
  for (auto p = run.err.find("ignored a result for cmd-spoofed"); p != std::string::npos;
       p = run.err.find("ignored a result for cmd-spoofed", p + 1)) {
    ++ignored;
  }
  EXPECT_EQ(ignored, 2u) << run.err;
  EXPECT_NE(run.err.find("signature_invalid"), std::string::npos) << run.err;
}

TEST(CommandMqtt, ToolExitsThreeWithoutAnswerAndTwoOnUsageErrors) {
  fleetgw::testing::MosquittoBroker broker;
  broker.start();
  fleetgw::testing::TempDir dir;
  const auto key_file = dir.path() / "ops.pem";
  Ed25519PrivateKey::generate().write_pem(key_file);
  auto o = tool_options(broker, key_file, "seat", "unlock");
  o.timeout = 2s;
  auto f = launch_tool(o);  // nobody answers
  const ToolRun r = f.get();
  EXPECT_EQ(r.exit_code, kExitNoAnswer) << r.err;
  EXPECT_TRUE(r.out.empty());

  auto bad = tool_options(broker, key_file, "seat", "open");
  std::ostringstream sink;
  bad.out = &sink;
  bad.err = &sink;
  EXPECT_EQ(run_command_tool(bad), kExitUsage);
  auto creds = tool_options(broker, key_file, "seat", "unlock");
  creds.username = "ops";
  creds.password = "secret";
  creds.out = &sink;
  creds.err = &sink;
  EXPECT_EQ(run_command_tool(creds), kExitUsage);  // no passwords over plain tcp://
  EXPECT_EQ(sink.str().find("secret"), std::string::npos);
  auto nokey = tool_options(broker, dir.path() / "missing.pem", "seat", "unlock");
  nokey.out = &sink;
  nokey.err = &sink;
  EXPECT_EQ(run_command_tool(nokey), kExitUsage);
}

TEST(Keygen, WritesAPrivateKeyOnlyTheOwnerCanReadAndAConfigLine) {
  fleetgw::testing::TempDir dir;
  std::ostringstream out, err;
  ASSERT_EQ(run_keygen(dir.path() / "backend-7", out, err), 0) << err.str();
  struct stat st {};
  ASSERT_EQ(::stat((dir.path() / "backend-7.pem").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const std::string line = out.str();
  ASSERT_EQ(line.rfind("backend-7 = \"", 0), 0u) << line;
  const std::string pub = line.substr(13, line.find('"', 13) - 13);
  const auto key = Ed25519PrivateKey::load_pem(dir.path() / "backend-7.pem");
  EXPECT_EQ(key.public_key().base64(), pub);
  // The printed line is accepted by the verifier as a trusted key.
  VerifierConfig vc;
  vc.vehicle_id = kVehicle;
  vc.trusted_keys["backend-7"] = pub;
  EXPECT_NO_THROW(CommandVerifier{vc});
  // Never overwrites a key.
  std::ostringstream out2, err2;
  EXPECT_NE(run_keygen(dir.path() / "backend-7", out2, err2), 0);
  EXPECT_EQ(Ed25519PrivateKey::load_pem(dir.path() / "backend-7.pem").public_key().base64(), pub);
}

}  // namespace
}  // namespace fleetgw::command::testing
