// `fleetgw command` under MQTT 5 (issue 15), through a real mosquitto: the command's publish
// carries a message expiry interval equal to the command's own validity, so a broker that queues
// it for an offline vehicle drops it once stale; a valid one queued beside it still arrives.
// Under --mqtt-version 3.1.1 there is no expiry and the stale command reaches the vehicle (the
// gateway then refuses it as expired; that is the command verifier's test).
#include <gtest/gtest.h>

#include <chrono>
#include <sstream>
#include <string>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/signing.h"
#include "gateway/tools/operator/command_tool.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/temp_dir.h"
#include "tests/uplink/mqtt5_test_util.h"

namespace fleetgw::command {
namespace {

using namespace std::chrono_literals;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::Received5;
using fleetgw::testing::Subscriber5;

struct Fixture {
  Fixture() {
    broker.start();
    std::ostringstream out, err;
    EXPECT_EQ(run_keygen(dir.path() / "operator", out, err), 0) << err.str();
  }
  // Sends one unlock to `vehicle`; nobody answers, so the tool gives up after `wait`.
  int send(const std::string& vehicle, const std::string& id, std::chrono::seconds expires_in,
           std::chrono::seconds wait, const std::string& version = "5") {
    CommandToolOptions o;
    o.vehicle = vehicle;
    o.lock = "seat";
    o.action = "unlock";
    o.key = dir.path() / "operator.pem";
    o.broker = broker.uri();
    o.timeout = wait;
    o.expires_in = expires_in;
    o.command_id = id;
    o.mqtt_version = version;
    std::ostringstream out;
    o.out = &out;
    o.err = &err;
    return run_command_tool(o);
  }
  MosquittoBroker broker;
  fleetgw::testing::TempDir dir;
  std::ostringstream err;
};

std::string command_id_of(const Received5& m) {
  v1::SignedCommand signed_cmd;
  v1::Command cmd;
  if (!signed_cmd.ParseFromString(m.payload) || !cmd.ParseFromString(signed_cmd.command())) {
    return "<undecodable>";
  }
  return cmd.command_id();
}

TEST(CommandMqtt5, ToolSetsTheMessageExpiryToTheCommandsValidity) {
  Fixture f;
  Subscriber5 vehicle(f.broker.uri(), "fleet/v1/bike-exp/cmd", "bike-exp");
  // 4 s: a second Paho client in one process may take ~2 s to connect (docs/uplink.md).
  EXPECT_EQ(f.send("bike-exp", "cmd-expiry", 30s, 4s), kExitNoAnswer) << f.err.str();
  ASSERT_TRUE(vehicle.wait_until([](const auto& m) { return !m.empty(); }, 5s)) << f.broker.log();
  const Received5 m = vehicle.messages().front();
  EXPECT_EQ(command_id_of(m), "cmd-expiry");
  ASSERT_TRUE(m.expiry_s.has_value()) << "no MESSAGE_EXPIRY_INTERVAL on the command";
  // The broker forwards what is left of it (the tool's 30 s minus the time in the broker).
  EXPECT_LE(*m.expiry_s, 30);
  EXPECT_GE(*m.expiry_s, 28);
  EXPECT_EQ(m.content_type, "application/x-protobuf; proto=fleetgw.v1.SignedCommand");
}

// `version` is the tool's protocol; the vehicle's session is MQTT 5 either way.
std::vector<std::string> delivered_after_an_outage(Fixture& f, const std::string& version) {
  const std::string vehicle = "bike-off";
  const std::string topic = "fleet/v1/" + vehicle + "/cmd";
  // The vehicle's persistent session exists (subscribed to cmd), then the vehicle goes away.
  { Subscriber5 gone(f.broker.uri(), topic, vehicle, true); }
  const auto first_sent = std::chrono::steady_clock::now();
  EXPECT_EQ(f.send(vehicle, "cmd-stale", 1s, 2s, version), kExitNoAnswer) << f.err.str();
  EXPECT_EQ(f.send(vehicle, "cmd-fresh", 60s, 1s, version), kExitNoAnswer) << f.err.str();
  // mosquitto counts expiry in whole seconds: the 1 s command is stale after 2 s for sure (the
  // two tool runs above waited 3 s for answers).
  EXPECT_GE(std::chrono::steady_clock::now() - first_sent, 2s);
  Subscriber5 back(f.broker.uri(), topic, vehicle, true);
  // Queued messages arrive in order: once the fresh one is in, the stale one would be too.
  EXPECT_TRUE(back.wait_until(
      [](const auto& m) {
        return std::any_of(m.begin(), m.end(),
                           [](const auto& r) { return command_id_of(r) == "cmd-fresh"; });
      },
      10s))
      << f.broker.log();
  std::vector<std::string> ids;
  for (const auto& m : back.messages()) ids.push_back(command_id_of(m));
  return ids;
}

TEST(CommandMqtt5, BrokerDropsACommandThatExpiredWhileTheVehicleWasOffline) {
  Fixture f;
  EXPECT_EQ(delivered_after_an_outage(f, "5"), std::vector<std::string>{"cmd-fresh"});
}

TEST(CommandMqtt5, Mqtt311CommandHasNoExpiryAndReachesTheVehicleStale) {
  Fixture f;
  EXPECT_EQ(delivered_after_an_outage(f, "3.1.1"),
            (std::vector<std::string>{"cmd-stale", "cmd-fresh"}));
}

}  // namespace
}  // namespace fleetgw::command
