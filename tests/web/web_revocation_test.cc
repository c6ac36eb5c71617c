// Revocation lists from the console (issue 28) through the real stack: the fleet root signs a
// list offline with the real `fleetgw keys revoke`; an admin uploads it; fleetgw-serve verifies
// it against --root-key and the last version, publishes it retained on the vehicle's
// revocations topic of a real mosquitto, stores and audits it; the real `fleetgw run` bike then
// refuses the console's own key with the reason `revoked`, shown in the console.
#include <gtest/gtest.h>
#include <sodium.h>

#include <nlohmann/json.hpp>

#include "tests/support/wait.h"
#include "tests/web/web_command_e2e.h"
#include "tests/web/web_command_util.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

std::string b64_of_file(const fs::path& file) {
  const std::string raw = read_text_file(file);
  std::string out(sodium_base64_ENCODED_LEN(raw.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), reinterpret_cast<const unsigned char*>(raw.data()),
                    raw.size(), sodium_base64_VARIANT_ORIGINAL);
  out.pop_back();  // the terminating NUL
  return out;
}

// `fleetgw keys revoke` as the root's holder runs it, offline.
fs::path revoke(const CommandRig& rig, const std::string& root_pem, const std::string& root_id,
                int version, const std::string& name) {
  const fs::path out = rig.dir.path() / name;
  run_program({FLEETGW_BINARY, "keys", "revoke", "--root", root_pem, "--root-id", root_id,
               "--version", std::to_string(version), "--serial", "7", "--out", out.string()},
              rig.dir.path() / (name + ".log"));
  return out;
}

TEST(WebRevocation, AdminUploadsARootsListAndTheRealBikeRefusesTheRevokedKey) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  CommandRig rig(
      "rev-bike",
      RigDelegation{.actions = {"lock", "unlock"}, .vehicle_ids = {"rev-bike"}, .groups = {}});
  ASSERT_EQ(rig.stack->add_operator("ada", "admin", "admin-password"), 0);
  const LoginResult ada = rig.stack->login("ada", "admin-password");
  const LoginResult olga = rig.stack->login("olga", "operator-password");
  ASSERT_EQ(ada.status, 200);
  auto lock = [&] {
    auto res = rig.stack->client().Post("/api/vehicles/rev-bike/commands",
                                        {{"Cookie", olga.cookie}, {"X-CSRF-Token", olga.csrf}},
                                        json{{"action", "lock"}}.dump(), "application/json");
    EXPECT_TRUE(res && res->status == 202) << (res ? res->body : "no answer");
    const std::string id = json::parse(res->body)["command_id"];
    json c;
    EXPECT_TRUE(wait_until(
        [&] {
          auto r = rig.stack->client().Get("/api/commands?ids=" + id, {{"Cookie", olga.cookie}});
          if (!r || r->status != 200) return false;
          c = json::parse(r->body)["commands"][0];
          return !c["result"].is_null();
        },
        30s, 20ms))
        << rig.logs();
    return c;
  };
  auto upload = [&](const LoginResult& who, const std::string& b64) {
    return rig.stack->client().Post("/api/revocations",
                                    {{"Cookie", who.cookie}, {"X-CSRF-Token", who.csrf}},
                                    json{{"list_base64", b64}}.dump(), "application/json");
  };
  ASSERT_EQ(lock().value("result", ""), "succeeded") << rig.logs();

  const std::string root_pem = (rig.dir.path() / "root-1.pem").string();
  const fs::path list1 = revoke(rig, root_pem, "root-1", 1, "rev-1.pb");
  const std::string b64 = b64_of_file(list1);

  // An operator may not; a forged list (another root's key under the name root-1) and an
  // unknown root are refused, naming what is wrong; nothing is published or stored.
  auto as_operator = upload(olga, b64);
  ASSERT_TRUE(as_operator);
  EXPECT_EQ(as_operator->status, 403);
  const fs::path other = rig.dir.path() / "other-root.pem";
  make_key(other, fs::perms::owner_read | fs::perms::owner_write);
  auto forged = upload(ada, b64_of_file(revoke(rig, other.string(), "root-1", 1, "forged.pb")));
  EXPECT_EQ(forged->status, 400);
  EXPECT_NE(forged->body.find("signature: does not verify with root 'root-1'"), std::string::npos)
      << forged->body;
  auto unknown = upload(ada, b64_of_file(revoke(rig, other.string(), "root-9", 1, "r9.pb")));
  EXPECT_EQ(unknown->status, 400);
  EXPECT_NE(unknown->body.find("root_key_id 'root-9' is not one of this server's --root-key"),
            std::string::npos)
      << unknown->body;
  EXPECT_EQ(upload(ada, "%%%")->status, 400);
  EXPECT_EQ(rig.stack->rows("SELECT count(*) FROM console_revocation_lists"),
            (std::vector<std::vector<std::string>>{{"0"}}));

  // The admin's upload: published, stored, audited with who and from where.
  auto ok = upload(ada, b64);
  ASSERT_TRUE(ok);
  ASSERT_EQ(ok->status, 200) << ok->body << rig.logs();
  EXPECT_EQ(json::parse(ok->body)["vehicles"], 1);
  EXPECT_EQ(rig.stack->rows("SELECT operator, address, target, result FROM console_audit WHERE "
                            "action = 'revocations_publish' AND result = 'ok'"),
            (std::vector<std::vector<std::string>>{{"ada", "127.0.0.1", "root-1/1", "ok"}}));
  auto list = rig.stack->client().Get("/api/revocations", {{"Cookie", ada.cookie}});
  const json in_force = json::parse(list->body)["in_force"];
  ASSERT_EQ(in_force.size(), 1u) << list->body;
  EXPECT_EQ(in_force[0]["version"], 1);
  EXPECT_EQ(in_force[0]["revoked_serials"], json::array({7}));
  EXPECT_EQ(in_force[0]["published_by"], "ada");
  EXPECT_EQ(rig.stack->client().Get("/api/revocations", {{"Cookie", olga.cookie}})->status, 403);

  // The same version again, or an older one: refused as the bikes would.
  auto again = upload(ada, b64);
  EXPECT_EQ(again->status, 409) << again->body;

  // The bike took the retained list: the console's key (delegation serial 7) is refused.
  ASSERT_TRUE(wait_until(
      [&] { return rig.gateway->log().find("revocation list version 1") != std::string::npos; },
      30s, 20ms))
      << rig.logs();
  const json refused = lock();
  EXPECT_EQ(refused.value("result", ""), "rejected") << refused.dump() << rig.logs();
  EXPECT_EQ(refused.value("reason", "").rfind("revoked", 0), 0u) << refused.dump();
}

}  // namespace
}  // namespace fleetgw::testing
