// `fleetgw serve` under a delegation of the fleet root (issue 28): the SignedCommand carries the
// delegation, the key id is the delegated one, and an action or vehicle outside the
// delegation's scope is refused before anything is published, with the reason.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/support/mosquitto_fixture.h"
#include "tests/support/wait.h"
#include "tests/web/web_command_util.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace std::chrono_literals;

constexpr auto kPrivate = fs::perms::owner_read | fs::perms::owner_write;

TEST(WebDelegation, CommandsCarryTheDelegationAndStayInsideItsScope) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  MosquittoBroker broker;
  broker.start();
  TempDir keys("fleetgw-web-deleg");
  make_key(keys.path() / "root.pem", kPrivate);
  make_key(keys.path() / "console.pem", kPrivate);
  v1::Delegation d;
  d.set_serial(7);
  d.set_key_id("console-berlin");
  d.set_public_key(public_key(keys.path() / "console.pem"));
  d.add_actions("lock");
  d.add_actions("speed_limit");
  d.add_vehicle_ids("bike-in");
  d.set_not_before_us(now_us() - 3'600'000'000LL);
  d.set_not_after_us(now_us() + 3'600'000'000LL);
  d.set_issued_at_us(now_us());
  d.set_holder("console test");
  const std::string delegation = sign_delegation(keys.path() / "root.pem", "root-1", d);
  std::ofstream(keys.path() / "console.delegation", std::ios::binary) << delegation;

  ServeStack stack({"--broker", broker.uri(), "--signing-key",
                    (keys.path() / "console.pem").string(), "--delegation",
                    (keys.path() / "console.delegation").string()});
  ASSERT_EQ(stack.add_operator("olga", "operator", "operator-password"), 0);
  stack.insert_vehicle({.id = "bike-in", .lat = 48.1, .lon = 11.5});
  stack.insert_vehicle({.id = "bike-out", .lat = 48.1, .lon = 11.5});
  TopicClient bikes(broker.uri(), "fleet/v1/+/cmd");
  const LoginResult olga = stack.login("olga", "operator-password");
  auto post = [&](const std::string& vehicle, const json& body) {
    return stack.client().Post("/api/vehicles/" + vehicle + "/commands",
                               {{"Cookie", olga.cookie}, {"X-CSRF-Token", olga.csrf}}, body.dump(),
                               "application/json");
  };

  // Outside the scope: refused here, audited, never published.
  auto unlock = post("bike-in", {{"action", "unlock"}});
  ASSERT_TRUE(unlock);
  EXPECT_EQ(unlock->status, 403);
  EXPECT_NE(unlock->body.find("action 'unlock' is not delegated"), std::string::npos)
      << unlock->body;
  auto other = post("bike-out", {{"action", "lock"}});
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 403);
  EXPECT_NE(other->body.find("not in the scope"), std::string::npos) << other->body;
  EXPECT_EQ(stack.rows("SELECT count(*) FROM console_audit WHERE result = 'out_of_scope'"),
            (std::vector<std::vector<std::string>>{{"2"}}));

  // Inside: signed by the delegated key, the delegation in field 4.
  auto lock = post("bike-in", {{"action", "lock"}});
  ASSERT_TRUE(lock);
  ASSERT_EQ(lock->status, 202) << lock->body << stack.log();
  std::string payload;
  ASSERT_TRUE(wait_until(
      [&] {
        const auto m = bikes.messages();
        if (m.empty()) return false;
        payload = m.front().second;
        return true;
      },
      10s));
  EXPECT_EQ(bikes.messages().size(), 1u) << "the refused commands were published";
  v1::SignedCommand sc;
  ASSERT_TRUE(sc.ParseFromString(payload));
  EXPECT_EQ(sc.key_id(), "console-berlin");
  EXPECT_EQ(sc.delegation().SerializeAsString(), delegation);
  EXPECT_TRUE(
      ed25519_verifies(public_key(keys.path() / "console.pem"), sc.command(), sc.signature()));
  auto config = stack.client().Get("/api/config", {{"Cookie", olga.cookie}});
  ASSERT_TRUE(config);
  const json c = json::parse(config->body)["commands"];
  EXPECT_EQ(c["key_id"], "console-berlin");
  EXPECT_EQ(c["actions"], json({"lock", "speed_limit"}));

  // A delegation of another key than --signing-key is refused at start, naming both.
  make_key(keys.path() / "other.pem", kPrivate);
  const fs::path out = keys.path() / "mismatch.log";
  const int rc = run_for_exit_code(
      {FLEETGW_SERVE_BINARY, "--pg", stack.conninfo(), "--listen", "127.0.0.1:0", "--broker",
       broker.uri(), "--signing-key", (keys.path() / "other.pem").string(), "--delegation",
       (keys.path() / "console.delegation").string()},
      out);
  EXPECT_EQ(rc, 1);
  EXPECT_NE(read_text_file(out).find("whose public key is not that of --signing-key"),
            std::string::npos)
      << read_text_file(out);
}

}  // namespace
}  // namespace fleetgw::testing
