// `fleetgw command` when no result comes (issue 16): the real binary and a real mosquitto. The
// tool reads the retained status the gateway's uplink keeps on <prefix>/<V>/status and says
// "offline since <time>", "connection lost (last will)", "online but it did not answer" or
// "never seen"; the exit status stays 3 (docs/commands.md). One case uses a real `fleetgw run`
// that connects and stops cleanly, the others retained messages published with mosquitto_pub.
#include <gtest/gtest.h>

#include <cstdlib>
#include <ctime>

#include "tests/config/cli_test_util.h"
#include "tests/support/mosquitto_fixture.h"

namespace fleetgw::testing::command_liveness {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kConnectedUs = 1732701600LL * 1'000'000;    // 2024-11-27T10:00:00Z
constexpr std::int64_t kStoppedUs = kConnectedUs + 3'723'000'000;  // 2024-11-27T11:02:03Z

std::string varint(std::uint64_t v) {
  std::string out;
  while (v >= 0x80) {
    out += static_cast<char>((v & 0x7F) | 0x80);
    v >>= 7;
  }
  out += static_cast<char>(v);
  return out;
}

// A fleetgw.v1.Envelope with a Status body, protobuf-encoded by hand (field numbers from
// proto/fleetgw/v1/envelope.proto and status.proto), so this test needs no generated code.
std::string status_envelope(const std::string& vehicle, std::int64_t created_us, int state,
                            bool last_will, std::int64_t connected_us) {
  std::string status = "\x08" + varint(static_cast<std::uint64_t>(state));  // state = 1
  if (last_will) status += std::string("\x70\x01");                         // last_will = 14
  status += "\x78" + varint(static_cast<std::uint64_t>(connected_us));      // connected_at_us
  std::string env = "\x0a" + varint(vehicle.size()) + vehicle;              // vehicle_id = 1
  if (created_us != 0) env += "\x18" + varint(static_cast<std::uint64_t>(created_us));
  env += "\x82\x01" + varint(status.size()) + status;  // status = 16
  return env;
}

class CommandLiveness : public ::testing::Test {
 protected:
  void SetUp() override {
    broker_.start();
    const Result k = run({FLEETGW_BIN, "keygen", (dir_.path() / "ops").string()}, dir_.path());
    ASSERT_EQ(k.code, 0) << k.err;
  }
  void retain(const std::string& vehicle, const std::string& payload) {
    const fs::path file = dir_.path() / ("status-" + vehicle + ".bin");
    write_text_file(file, payload);
    run_program({"mosquitto_pub", "-h", "127.0.0.1", "-p", std::to_string(broker_.port()), "-q",
                 "1", "-r", "-t", "fleet/v1/" + vehicle + "/status", "-f", file.string()},
                dir_.path() / "pub.log");
  }
  Result command(const std::string& vehicle) {
    return run({FLEETGW_BIN, "command", "--vehicle", vehicle, "--lock", "seat", "--action",
                "unlock", "--key", (dir_.path() / "ops.pem").string(), "--broker", broker_.uri(),
                "--timeout-s", "1"},
               dir_.path());
  }

  MosquittoBroker broker_;
  TempDir dir_{"fleetgw-cmd-liveness"};
};

TEST_F(CommandLiveness, NeverSeenVehicleNamesTheStatusTopic) {
  const Result r = command("bike-ghost");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_NE(r.err.find("vehicle bike-ghost never seen (no retained status on "
                       "fleet/v1/bike-ghost/status)"),
            std::string::npos)
      << r.err;
}

TEST_F(CommandLiveness, CleanlyStoppedVehicleIsOfflineSinceItsLastStatus) {
  retain("bike-parked", status_envelope("bike-parked", kStoppedUs, 2, false, kConnectedUs));
  const Result r = command("bike-parked");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("vehicle bike-parked offline since 2024-11-27T11:02:03Z"), std::string::npos)
      << r.err;
}

TEST_F(CommandLiveness, LostConnectionIsReportedFromTheLastWill) {
  retain("bike-lost", status_envelope("bike-lost", 0, 2, true, kConnectedUs));
  const Result r = command("bike-lost");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("vehicle bike-lost offline: its connection was lost (last will); it had "
                       "connected at 2024-11-27T10:00:00Z"),
            std::string::npos)
      << r.err;
}

TEST_F(CommandLiveness, OnlineButSilentAndGarbageStatus) {
  retain("bike-mute", status_envelope("bike-mute", kStoppedUs, 1, false, kConnectedUs));
  const Result r = command("bike-mute");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("vehicle bike-mute online (status of 2024-11-27T11:02:03Z) but it did not "
                       "answer"),
            std::string::npos)
      << r.err;
  retain("bike-junk", std::string("\xff\xff\xff\xff garbage", 12));
  const Result junk = command("bike-junk");
  EXPECT_EQ(junk.code, 3) << junk.err;
  EXPECT_NE(junk.err.find("is not a fleetgw status"), std::string::npos) << junk.err;
}

// The real gateway: it connects, publishes its retained online status, stops cleanly and leaves
// the retained offline status, stamped with the time it stopped.
TEST_F(CommandLiveness, RealGatewayThatStoppedIsOfflineSinceItStopped) {
  const fs::path file = dir_.path() / "fleetgw.toml";
  write_text_file(
      file, "[vehicle]\nid = \"bike-real\"\n[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" +
                std::string(FLEETGW_SOURCE_DIR) +
                "/config/scenarios/demo.toml\"\nspeed = 1\nlockstep = true\n[storage]\npath = \"" +
                (dir_.path() / "fleetgw.db").string() +
                "\"\n[status]\nsocket = \"\"\n[mqtt]\nenabled = true\nuri = \"" + broker_.uri() +
                "\"\ntopic_prefix = \"fleet/v1\"\n");
  Child service({FLEETGW_BIN, "run", "--config", file.string(), "--duration", "60"},
                dir_.path() / "svc.out", dir_.path() / "svc.err");
  ASSERT_TRUE(
      wait_until([&] { return broker_.log().find("fleet/v1/bike-real/cmd") != std::string::npos; },
                 std::chrono::seconds(30)))
      << service.err() << broker_.log();
  service.signal(SIGTERM);
  ASSERT_EQ(service.wait(std::chrono::seconds(20)), 0) << service.err();
  const std::time_t stopped = std::time(nullptr);

  const Result r = command("bike-real");
  EXPECT_EQ(r.code, 3) << r.err;
  const std::string marker = "vehicle bike-real offline since ";
  const auto at = r.err.find(marker);
  ASSERT_NE(at, std::string::npos) << r.err;
  std::tm tm{};
  const std::string when = r.err.substr(at + marker.size(), 20);
  ASSERT_NE(strptime(when.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm), nullptr) << when;
  EXPECT_LE(std::llabs(static_cast<long long>(timegm(&tm) - stopped)), 5) << when;
}

}  // namespace
}  // namespace fleetgw::testing::command_liveness
