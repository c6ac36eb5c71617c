// `fleetgw check-config` and `fleetgw run` against the real binary: one validation path. Every
// configuration `run` refuses, check-config refuses too, with the same file:line:key messages,
// and both report every problem at once (issue 11, item 6). Also the CLI's exit codes for bad
// option values, an unknown command, and `fleetgw status --config`.
#include <gtest/gtest.h>

#include "tests/config/cli_test_util.h"
#include "tests/support/mosquitto_fixture.h"

namespace fleetgw::testing {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

const std::string kBin = FLEETGW_BIN;
const std::string kSource = FLEETGW_SOURCE_DIR;

// 1-based line of the first line of `text` that starts with `prefix`.
int line_of(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.rfind(prefix, 0) == 0) return n;
  }
  ADD_FAILURE() << "no line starting with " << prefix;
  return -1;
}

class CheckConfig : public ::testing::Test {
 protected:
  // A configuration `run` accepts: the simulated bike, the store in the test directory, no
  // status socket. `extra` is appended (later tables may add keys to these ones only via
  // `sections`).
  std::string base(const std::string& storage_path = "") const {
    return "[can]\ntransport = \"sim\"\n"
           "[sim]\nscenario = \"" +
           kSource +
           "/config/scenarios/demo.toml\"\nspeed = 20\n"
           "[storage]\npath = \"" +
           (storage_path.empty() ? (dir_.path() / "fleetgw.db").string() : storage_path) +
           "\"\n[status]\nsocket = \"\"\n";
  }
  fs::path write(const std::string& text, const std::string& name = "fleetgw.toml") {
    const fs::path p = dir_.path() / name;
    write_text_file(p, text);
    return p;
  }
  Result check(const fs::path& file) {
    return run({kBin, "check-config", file.string()}, dir_.path());
  }
  Result start(const fs::path& file, const std::string& duration = "1") {
    return run({kBin, "run", "--config", file.string(), "--duration", duration}, dir_.path());
  }
  // Both commands refuse the file with `expected` among the messages; returns check's stderr.
  std::string expect_both_refuse(const fs::path& file, const std::string& expected) {
    const Result c = check(file);
    EXPECT_EQ(c.code, 1) << c.out << c.err;
    EXPECT_NE(c.err.find(expected), std::string::npos) << "check-config said:\n" << c.err;
    EXPECT_EQ(c.out.find("OK"), std::string::npos) << c.out;
    const Result r = start(file);
    EXPECT_EQ(r.code, 1) << r.out << r.err;
    EXPECT_NE(r.err.find(expected), std::string::npos) << "run said:\n" << r.err;
    return c.err;
  }

  TempDir dir_{"fleetgw-check-config"};
};

TEST_F(CheckConfig, ValidConfigIsOkAndRunStarts) {
  const auto file = write(base());
  const Result c = check(file);
  EXPECT_EQ(c.code, 0) << c.err;
  EXPECT_EQ(c.out, file.string() + ": OK\n");
  const Result r = start(file);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_.path() / "fleetgw.db"));
}

TEST_F(CheckConfig, MalformedTrustedKeyIsRefusedWithItsLine) {
  const std::string text = base() + "[command.trusted_keys]\nops = \"not-a-key\"\n";
  const auto file = write(text);
  expect_both_refuse(file, file.string() + ":" + std::to_string(line_of(text, "ops =")) +
                               ": command.trusted_keys.ops: not a base64 raw Ed25519 public key");
  EXPECT_FALSE(fs::exists(dir_.path() / "fleetgw.db")) << "run opened the store anyway";
}

TEST_F(CheckConfig, BrokerUriWithUserInfoIsRefusedWithoutEchoingThePassword) {
  const std::string text =
      base() + "[mqtt]\nenabled = true\nuri = \"tcp://gw:s3cr3t-pw@127.0.0.1:1883\"\n";
  const auto file = write(text);
  const std::string err = expect_both_refuse(
      file, file.string() + ":" + std::to_string(line_of(text, "uri =")) +
                ": mqtt.uri: 'tcp://***@127.0.0.1:1883' contains user information");
  EXPECT_EQ(err.find("s3cr3t-pw"), std::string::npos) << err;
}

TEST_F(CheckConfig, CredentialsOverPlainTcpNameRealKeys) {
  const std::string text = base() +
                           "[mqtt]\nenabled = true\nuri = \"tcp://127.0.0.1:1883\"\n"
                           "username = \"bike\"\npassword = \"s3cr3t-pw\"\n";
  const auto file = write(text);
  const std::string err = expect_both_refuse(
      file, file.string() + ":" + std::to_string(line_of(text, "username =")) +
                ": mqtt.username: credentials over unencrypted tcp:// are refused");
  EXPECT_EQ(err.find("allow_plaintext_credentials"), std::string::npos) << err;
  EXPECT_EQ(err.find("uplink.username"), std::string::npos) << err;
  EXPECT_EQ(err.find("s3cr3t-pw"), std::string::npos) << err;
}

TEST_F(CheckConfig, MissingReplayFileIsRefused) {
  const std::string text = "[can]\ntransport = \"replay\"\nreplay_file = \"" +
                           (dir_.path() / "missing.log").string() + "\"\n[storage]\npath = \"" +
                           (dir_.path() / "fleetgw.db").string() + "\"\n[status]\nsocket = \"\"\n";
  const auto file = write(text);
  expect_both_refuse(file, file.string() + ":" + std::to_string(line_of(text, "replay_file")) +
                               ": can.replay_file: '" + (dir_.path() / "missing.log").string() +
                               "' does not exist");
}

// Issue 14: the simulated GNSS receiver serves the scenario's route; demo.toml has none.
TEST_F(CheckConfig, NmeaPtyWithoutARouteIsRefused) {
  const std::string scenario = kSource + "/config/scenarios/demo.toml";
  const std::string text = "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + scenario +
                           "\"\nnmea_pty = \"" + (dir_.path() / "gps").string() +
                           "\"\n[storage]\npath = \"" + (dir_.path() / "fleetgw.db").string() +
                           "\"\n[status]\nsocket = \"\"\n";
  expect_both_refuse(write(text), "sim.nmea_pty: scenario " + scenario + " has no [[route]]");
  EXPECT_FALSE(fs::exists(dir_.path() / "gps"));
}

TEST_F(CheckConfig, MissingStorageDirectoryIsRefusedAndNotCreated) {
  const fs::path missing = dir_.path() / "no-such-dir";
  const std::string text = base((missing / "fleetgw.db").string());
  const auto file = write(text);
  expect_both_refuse(file, file.string() + ":" + std::to_string(line_of(text, "path =")) +
                               ": storage.path: directory '" + missing.string() +
                               "' does not exist");
  EXPECT_FALSE(fs::exists(missing)) << "run created the storage directory";
}

TEST_F(CheckConfig, NanAndInfinityAreRefused) {
  std::string text = base();
  text.replace(text.find("speed = 20"), 10, "speed = nan");
  text += "[ride]\nmoving_speed_kmh = inf\n";
  const auto file = write(text);
  const std::string err =
      expect_both_refuse(file, file.string() + ":" + std::to_string(line_of(text, "speed =")) +
                                   ": sim.speed: nan is not a finite number");
  EXPECT_NE(err.find(":" + std::to_string(line_of(text, "moving_speed_kmh")) +
                     ": ride.moving_speed_kmh: inf is not a finite number"),
            std::string::npos)
      << err;
}

TEST_F(CheckConfig, DirectoryInsteadOfAFileIsRefusedByBoth) {
  const fs::path d = dir_.path() / "conf.d";
  fs::create_directory(d);
  expect_both_refuse(d, d.string() + ": is a directory, not a configuration file");
}

TEST_F(CheckConfig, EveryProblemIsReportedAtOnce) {
  std::string text = base((dir_.path() / "gone" / "fleetgw.db").string());
  text.replace(text.find("speed = 20"), 10, "speed = nan");
  const auto file = write(text);
  // Load-time problems (nan) come first and stop there: the file cannot be trusted further.
  EXPECT_EQ(check(file).code, 1);
  // Without them, every run-time problem is listed in one go.
  text = base((dir_.path() / "gone" / "fleetgw.db").string()) +
         "[mqtt]\nenabled = true\nuri = \"tcp://u:p@127.0.0.1:1883\"\nusername = \"bike\"\n"
         "[command.trusted_keys]\nops = \"AAAA\"\nbackup = \"\"\n";
  write(text);
  const Result c = check(file);
  EXPECT_EQ(c.code, 1);
  for (const char* key : {": storage.path:", ": mqtt.uri:", ": mqtt.username:",
                          ": command.trusted_keys.ops:", ": command.trusted_keys.backup:"}) {
    EXPECT_NE(c.err.find(key), std::string::npos) << key << " missing from\n" << c.err;
  }
  EXPECT_NE(c.err.find("5 problem(s) in the configuration"), std::string::npos) << c.err;
}

TEST_F(CheckConfig, RunOverridesAreCheckedToo) {
  const auto file = write(base());
  const Result r = run({kBin, "run", "--config", file.string(), "--replay",
                        (dir_.path() / "nope.log").string(), "--duration", "1"},
                       dir_.path());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(
      r.err.find("can.replay_file: '" + (dir_.path() / "nope.log").string() + "' does not exist"),
      std::string::npos)
      << r.err;
}

TEST(Cli, BadOptionValuesExitWithTwo) {
  TempDir dir;
  EXPECT_EQ(run({kBin, "run", "--config", "x.toml", "--sim-speed", "-1"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "run", "--config", "x.toml", "--sim-speed", "fast"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "decode", "--crc-order", "middle"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "run", "--no-such-option"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "check-config"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "status", "--socket", "a", "--config", "b"}, dir.path()).code, 2);
  EXPECT_EQ(run({kBin, "--help"}, dir.path()).code, 0);
}

// A mistyped command is named, with where to look, and exits 2 -- also with --help after it
// (a script's typo must never look like success), at the top level and inside the groups.
TEST(Cli, UnknownCommandIsNamedAndExitsTwo) {
  TempDir dir;
  const std::string text = "fleetgw: unknown command 'nosuch'; see fleetgw --help";
  for (const std::vector<std::string>& args : {std::vector<std::string>{kBin, "nosuch"},
                                               {kBin, "nosuch", "--help"},
                                               {kBin, "nosuch", "run"}}) {
    const Result r = run(args, dir.path());
    EXPECT_EQ(r.code, 2) << args.size() << ": " << r.out << r.err;
    EXPECT_EQ(r.out, "") << "no help text for a typo";
    EXPECT_NE(r.err.find(text), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("A subcommand is required"), std::string::npos) << r.err;
  }
  const Result db = run({kBin, "db", "rids", "--help"}, dir.path());
  EXPECT_EQ(db.code, 2) << db.out;
  EXPECT_NE(db.err.find("unknown command 'db rids'; see fleetgw db --help"), std::string::npos)
      << db.err;
  const Result zones = run({kBin, "zones", "sing"}, dir.path());
  EXPECT_EQ(zones.code, 2);
  EXPECT_NE(zones.err.find("unknown command 'zones sing'; see fleetgw zones --help"),
            std::string::npos)
      << zones.err;
  // The hostile name is shown escaped: a command line cannot write to the terminal.
  const Result esc = run({kBin, "x\x1b[2J"}, dir.path());
  EXPECT_EQ(esc.code, 2);
  EXPECT_EQ(esc.err.find('\x1b'), std::string::npos) << esc.err;
  EXPECT_NE(esc.err.find("unknown command 'x\\x1b[2J'"), std::string::npos) << esc.err;
  // Real commands, their help and a missing command are unchanged.
  EXPECT_EQ(run({kBin, "db", "--help"}, dir.path()).code, 0);
  EXPECT_EQ(run({kBin, "db", "rides", "--help"}, dir.path()).code, 0);
  EXPECT_EQ(run({kBin, "--version"}, dir.path()).code, 0);
  const Result none = run({kBin}, dir.path());
  EXPECT_EQ(none.code, 2);
  EXPECT_NE(none.err.find("A subcommand is required"), std::string::npos) << none.err;
}

TEST(Cli, StatusConfigAsksTheConfiguredSocket) {
  TempDir dir;
  const fs::path sock = dir.path() / "gw-status.sock";
  const fs::path file = dir.path() / "fleetgw.toml";
  write_text_file(file, "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + kSource +
                            "/config/scenarios/demo.toml\"\nspeed = 1\n[storage]\npath = \"" +
                            (dir.path() / "fleetgw.db").string() + "\"\n[status]\nsocket = \"" +
                            sock.string() + "\"\n");
  // Nothing running: exit 3, naming the socket taken from the file.
  const Result none = run({kBin, "status", "--config", file.string()}, dir.path());
  EXPECT_EQ(none.code, 3);
  EXPECT_NE(none.err.find(sock.string()), std::string::npos) << none.err;

  Child service({kBin, "run", "--config", file.string(), "--duration", "60"},
                dir.path() / "svc.out", dir.path() / "svc.err");
  Result answer;
  ASSERT_TRUE(wait_until(
      [&] {
        answer = run({kBin, "status", "--config", file.string(), "--json"}, dir.path());
        return answer.code != 3;
      },
      std::chrono::seconds(20)))
      << service.err();
  EXPECT_TRUE(answer.code == 0 || answer.code == 1) << answer.err;
  EXPECT_NE(answer.out.find("\"vehicle_id\""), std::string::npos) << answer.out;
  service.signal(SIGTERM);
  EXPECT_EQ(service.wait(std::chrono::seconds(20)), 0) << service.err();
}

}  // namespace
}  // namespace fleetgw::testing
