// Commands from the console through the real stack (issue 28): fleetgw-serve signs for the
// operator and publishes to a real mosquitto; a real `fleetgw run` on a simulated bike (the
// parked scenario) verifies, moves the simulated locks and answers; the server stores the
// answer bound to the bytes it signed.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/wait.h"
#include "tests/web/web_command_e2e.h"
#include "tests/web/web_command_util.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

TEST(WebCommandE2E, OperatorUnlocksAndLocksARealGatewaysBike) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  CommandRig rig("e2e-bike");
  const LoginResult olga = rig.stack->login("olga", "operator-password");
  ASSERT_EQ(olga.status, 200);
  auto send = [&](const json& body) {
    auto res = rig.stack->client().Post("/api/vehicles/e2e-bike/commands",
                                        {{"Cookie", olga.cookie}, {"X-CSRF-Token", olga.csrf}},
                                        body.dump(), "application/json");
    EXPECT_TRUE(res);
    EXPECT_EQ(res->status, 202) << res->body;
    return json::parse(res->body).value("command_id", "");
  };
  auto final_result = [&](const std::string& id) {
    json c;
    wait_until(
        [&] {
          auto res = rig.stack->client().Get("/api/commands?ids=" + id, {{"Cookie", olga.cookie}});
          if (!res || res->status != 200) return false;
          const json j = json::parse(res->body)["commands"];
          if (j.empty() || j[0]["result"].is_null()) return false;
          c = j[0];
          return true;
        },
        30s, 20ms);
    return c;
  };

  const json unlocked = final_result(send({{"action", "unlock"}, {"lock_kind", "seat"}}));
  ASSERT_EQ(unlocked.value("result", ""), "succeeded") << unlocked.dump() << rig.logs();
  EXPECT_EQ(unlocked["final_state"], "unlocked");
  EXPECT_EQ(unlocked["result_operator"], "olga") << "the bike echoes the signed operator";
  const json locked = final_result(send({{"action", "lock"}, {"lock_kind", "seat"}}));
  ASSERT_EQ(locked.value("result", ""), "succeeded") << locked.dump() << rig.logs();
  EXPECT_EQ(locked["final_state"], "locked");
  // A lock kind this bike does not have: the bike's own reason comes back to the console.
  const json refused = final_result(send({{"action", "lock"}, {"lock_kind", "no_such_lock"}}));
  EXPECT_EQ(refused.value("result", ""), "rejected") << refused.dump();
  EXPECT_NE(refused.value("reason", "").find("lock_not_fitted"), std::string::npos)
      << refused.dump();
}

// The same through a root and a delegation (the bike trusts only the root key): the lock
// succeeds; a delegation scoped by a group the bike is not in passes the server (which cannot
// know the bike's groups) and the bike's refusal comes back to the console with its reason.
TEST(WebCommandE2E, DelegatedKeyLocksAndTheBikesScopeRefusalComesBack) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  for (const bool in_scope : {true, false}) {
    RigDelegation d{.actions = {"lock", "unlock"}};
    if (in_scope) {
      d.vehicle_ids = {"deleg-bike"};
    } else {
      d.groups = {"berlin"};
    }
    CommandRig rig("deleg-bike", d);
    const LoginResult olga = rig.stack->login("olga", "operator-password");
    auto res = rig.stack->client().Post("/api/vehicles/deleg-bike/commands",
                                        {{"Cookie", olga.cookie}, {"X-CSRF-Token", olga.csrf}},
                                        json{{"action", "lock"}}.dump(), "application/json");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 202) << res->body;
    const std::string id = json::parse(res->body)["command_id"];
    json c;
    ASSERT_TRUE(wait_until(
        [&] {
          auto r = rig.stack->client().Get("/api/commands?ids=" + id, {{"Cookie", olga.cookie}});
          if (!r || r->status != 200) return false;
          c = json::parse(r->body)["commands"][0];
          return !c["result"].is_null();
        },
        30s, 20ms))
        << rig.logs();
    if (in_scope) {
      EXPECT_EQ(c["result"], "succeeded") << c.dump() << rig.logs();
      EXPECT_EQ(c["result_operator"], "olga");
    } else {
      EXPECT_EQ(c["result"], "rejected") << c.dump();
      EXPECT_EQ(c.value("reason", "").rfind("out_of_scope", 0), 0u) << c.dump();
    }
  }
}

}  // namespace
}  // namespace fleetgw::testing
