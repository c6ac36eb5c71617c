// The configuration of delegated keys (issue 28): [vehicle] groups and [command.root_keys] are
// read, validated with file and line, reach the command verifier, and the shipped example
// documents them; an old file without them keeps loading.
#include <gtest/gtest.h>

#include <string>

#include "gateway/cli/check_config.h"
#include "gateway/command/command_service.h"
#include "gateway/command/ed25519.h"
#include "gateway/config/config.h"

namespace fleetgw::command {
namespace {

std::string problems_of(const std::string& toml) {
  try {
    const auto c = config::parse_config(toml, "test.toml");
    std::string out;
    for (const auto& p : cli::check_runnable(c)) out += p + "\n";
    return out;
  } catch (const config::ConfigError& e) {
    return e.what();
  }
}

TEST(DelegationConfig, GroupsAndRootKeysReachTheVerifier) {
  const auto root = Ed25519PrivateKey::generate().public_key().base64();
  const auto c = config::parse_config(
      "[vehicle]\nid = \"bike-7\"\ngroups = [\"berlin-north\", "
      "\"cargo\"]\n[command.root_keys]\nroot-1 = \"" +
          root + "\"\n",
      "test.toml");
  EXPECT_EQ(c.vehicle.groups, (std::vector<std::string>{"berlin-north", "cargo"}));
  const auto sc = make_command_service_config(c);
  EXPECT_EQ(sc.verifier.groups, c.vehicle.groups);
  ASSERT_EQ(sc.verifier.root_keys.count("root-1"), 1u);
  EXPECT_EQ(sc.verifier.root_keys.at("root-1"), root);
  CommandVerifier v(sc.verifier);
  EXPECT_NE(v.root_keys().find("root-1"), nullptr);
}

TEST(DelegationConfig, BadGroupsAreRefusedWithFileAndLine) {
  EXPECT_NE(problems_of("[vehicle]\ngroups = [\"berlin north\"]\n")
                .find("test.toml:2: vehicle.groups: element 0 must be 1..64 characters"),
            std::string::npos)
      << problems_of("[vehicle]\ngroups = [\"berlin north\"]\n");
  EXPECT_NE(problems_of("[vehicle]\ngroups = [\"a\", \"a\"]\n").find("('a') is repeated"),
            std::string::npos);
  EXPECT_NE(problems_of("[vehicle]\ngroups = \"a\"\n").find("expected an array"),
            std::string::npos);
}

TEST(DelegationConfig, BadRootKeyIsReportedByCheckConfigNamingIt) {
  const auto p = problems_of("[command.root_keys]\nroot-1 = \"not-a-key\"\n");
  EXPECT_NE(p.find("test.toml:2: command.root_keys.root-1: not a base64 raw Ed25519 public key"),
            std::string::npos)
      << p;
  const auto id = problems_of("[command.root_keys]\n\"root 1\" = \"" +
                              Ed25519PrivateKey::generate().public_key().base64() + "\"\n");
  EXPECT_NE(id.find("a root key id is 1..64 characters"), std::string::npos) << id;
}

TEST(DelegationConfig, AnOldConfigurationWithoutThemStillLoads) {
  const auto key = Ed25519PrivateKey::generate().public_key().base64();
  const auto c =
      config::parse_config("[command.trusted_keys]\nbackend-1 = \"" + key + "\"\n", "old.toml");
  EXPECT_TRUE(c.vehicle.groups.empty());
  EXPECT_TRUE(c.command.root_keys.empty());
  EXPECT_TRUE(cli::check_runnable(c).empty() ||
              cli::check_runnable(c).front().find("root_keys") == std::string::npos);
}

TEST(DelegationConfig, TheShippedExampleDocumentsAndParsesThem) {
  const auto c = config::load_config(FLEETGW_SOURCE_DIR "/config/fleetgw.toml");
  EXPECT_TRUE(c.vehicle.groups.empty());
  EXPECT_TRUE(c.command.root_keys.empty());
  EXPECT_GT(c.key_lines.count("vehicle.groups"), 0u);
}

}  // namespace
}  // namespace fleetgw::command
