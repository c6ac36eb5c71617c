// Delegated keys end to end (issue 28): the real binaries -- `fleetgw keys`, `fleetgw command`
// and `fleetgw run` on the simulated bike -- through a real mosquitto. A command signed under a
// valid delegation succeeds and its result names the operator; once the root's revocation list
// is published the same key is refused `revoked`, and still after a restart with the broker
// down at start-up and then empty (the list came from the store, not from the broker).
#include <gtest/gtest.h>

#include <csignal>
#include <string>

#include "tests/config/cli_test_util.h"
#include "tests/support/mosquitto_fixture.h"

namespace fleetgw::testing::delegation_e2e {
namespace {

namespace fs = std::filesystem;

class DelegationE2e : public ::testing::Test {
 protected:
  void SetUp() override {
    broker_.start();
    const Result root = keys({"root", "--out", path("root-1")});
    ASSERT_EQ(root.code, 0) << root.err;
    const Result d = keys({"delegate",     "--root",      path("root-1.pem"),
                           "--root-id",    "root-1",      "--key-id",
                           "console-1",    "--new-key",   path("console-1"),
                           "--actions",    "lock,unlock", "--groups",
                           "berlin-north", "--not-after", "2099-01-01T00:00:00Z",
                           "--serial",     "7",           "--holder",
                           "console",      "--out",       path("console-1.deleg")});
    ASSERT_EQ(d.code, 0) << d.err;
    write_text_file(
        dir_.path() / "fleetgw.toml",
        "[vehicle]\nid = \"bike-deleg\"\ngroups = [\"berlin-north\"]\n[can]\ntransport = "
        "\"sim\"\n[sim]\nscenario = \"" +
            std::string(FLEETGW_SOURCE_DIR) +
            "/config/scenarios/demo.toml\"\nspeed = 1\nlockstep = true\n[storage]\npath = \"" +
            path("fleetgw.db") + "\"\n[status]\nsocket = \"\"\n[mqtt]\nenabled = true\nuri = \"" +
            broker_.uri() + "\"\ntopic_prefix = \"fleet/v1\"\n" + "[command.root_keys]\n" +
            root.out);
  }

  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }
  Result keys(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "keys"});
    return run(args, dir_.path());
  }
  Result command(const std::string& action) {
    return run({FLEETGW_BIN, "command", "--vehicle", "bike-deleg", "--lock", "seat", "--action",
                action, "--key", path("console-1.pem"), "--delegation", path("console-1.deleg"),
                "--operator", "alice", "--broker", broker_.uri(), "--timeout-s", "15"},
               dir_.path(), std::chrono::seconds(40));
  }
  std::unique_ptr<Child> start_gateway(const std::string& tag) {
    return std::make_unique<Child>(
        std::vector<std::string>{FLEETGW_BIN, "run", "--config", path("fleetgw.toml"), "--duration",
                                 "120"},
        dir_.path() / ("svc-" + tag + ".out"), dir_.path() / ("svc-" + tag + ".err"));
  }
  // How often the broker's log names the command topic (each subscription does).
  std::size_t cmd_mentions() const {
    const std::string log = broker_.log();
    std::size_t n = 0;
    for (auto at = log.find("fleet/v1/bike-deleg/cmd "); at != std::string::npos;
         at = log.find("fleet/v1/bike-deleg/cmd ", at + 1)) {
      ++n;
    }
    return n;
  }
  bool subscribed(std::size_t times) const { return cmd_mentions() >= times; }

  MosquittoBroker broker_;
  TempDir dir_{"fleetgw-delegation-e2e"};
};

TEST_F(DelegationE2e, DelegatedCommandRunsThenItsRevokedKeyIsRefusedAlsoAfterARestartOffline) {
  auto gateway = start_gateway("1");
  ASSERT_TRUE(wait_until([&] { return subscribed(1); }, std::chrono::seconds(30)))
      << gateway->err() << broker_.log();

  const Result ok = command("unlock");
  EXPECT_EQ(ok.code, 0) << ok.out << ok.err << gateway->out() << gateway->err();
  EXPECT_NE(ok.out.find("\"result\":\"succeeded\""), std::string::npos) << ok.out;
  EXPECT_NE(ok.out.find("\"operator_id\":\"alice\""), std::string::npos) << ok.out;

  const Result list = keys({"revoke", "--root", path("root-1.pem"), "--root-id", "root-1",
                            "--version", "1", "--serial", "7", "--out", path("rev-1.pb")});
  ASSERT_EQ(list.code, 0) << list.err;
  const Result pub = keys({"publish-revocations", path("rev-1.pb"), "--vehicle", "bike-deleg",
                           "--broker", broker_.uri()});
  ASSERT_EQ(pub.code, 0) << pub.err;
  const auto log_of = [&](Child& c) { return c.out() + c.err(); };
  ASSERT_TRUE(wait_until(
      [&] { return log_of(*gateway).find("revocation list version 1") != std::string::npos; },
      std::chrono::seconds(20)))
      << log_of(*gateway);

  const Result refused = command("lock");
  EXPECT_EQ(refused.code, 1) << refused.out << refused.err;
  EXPECT_NE(refused.out.find("\"result\":\"rejected\""), std::string::npos) << refused.out;
  EXPECT_NE(refused.out.find("\"reason\":\"revoked: delegation 7 of root 'root-1' is revoked"),
            std::string::npos)
      << refused.out;
  EXPECT_NE(refused.out.find("\"operator_id\":\"alice\""), std::string::npos) << refused.out;

  // Restart with the broker down, then an empty broker: the list must come from the store.
  gateway->signal(SIGTERM);
  ASSERT_EQ(gateway->wait(std::chrono::seconds(20)), 0) << gateway->err();
  broker_.stop();
  auto restarted = start_gateway("2");
  ASSERT_TRUE(wait_until(
      [&] {
        return log_of(*restarted)
                   .find(
                       "revocation list version 1 "
                       "restored") != std::string::npos;
      },
      std::chrono::seconds(20)))
      << log_of(*restarted);
  broker_.start();  // no persistence: nothing retained
  const std::size_t before = cmd_mentions();
  ASSERT_TRUE(wait_until([&] { return subscribed(before + 1); }, std::chrono::seconds(40)))
      << restarted->err() << broker_.log();
  const Result still = command("lock");
  EXPECT_EQ(still.code, 1) << still.out << still.err;
  EXPECT_NE(still.out.find("\"reason\":\"revoked: "), std::string::npos) << still.out;
}

}  // namespace
}  // namespace fleetgw::testing::delegation_e2e
