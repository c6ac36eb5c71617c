// Operator accounts and zones from the console's admin pages (issue 28), against the real
// fleetgw-serve and PostgreSQL: admin-only (403 for the others, audited), CSRF-protected, the
// last admin kept; zone uploads refused with the field and place; login slowed after wrong
// passwords.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <fstream>

#include "tests/support/temp_dir.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using Rows = std::vector<std::vector<std::string>>;

class WebAccounts : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ = std::make_unique<ServeStack>();
    ASSERT_EQ(stack_->add_operator("ada", "admin", "admin-password"), 0);
    ASSERT_EQ(stack_->add_operator("olga", "operator", "operator-password"), 0);
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }
  static httplib::Result post(const LoginResult& who, const std::string& path, const json& body,
                              bool csrf = true) {
    httplib::Headers h = {{"Cookie", who.cookie}};
    if (csrf) h.emplace("X-CSRF-Token", who.csrf);
    return stack_->client().Post(path, h, body.dump(), "application/json");
  }
  static std::unique_ptr<ServeStack> stack_;
};
std::unique_ptr<ServeStack> WebAccounts::stack_;

TEST_F(WebAccounts, AnAdminAddsResetsDemotesAndRemovesAnOperatorAndOthersCannot) {
  const LoginResult ada = stack_->login("ada", "admin-password");
  const LoginResult olga = stack_->login("olga", "operator-password");
  ASSERT_EQ(ada.status, 200);
  // Only an admin, and only with the CSRF token.
  EXPECT_EQ(stack_->client().Get("/api/operators", {{"Cookie", olga.cookie}})->status, 403);
  const json nick = {{"name", "nick"}, {"role", "operator"}, {"password", "nick-password-1"}};
  EXPECT_EQ(post(olga, "/api/operators", nick)->status, 403);
  EXPECT_EQ(post(ada, "/api/operators", nick, /*csrf=*/false)->status, 403);
  auto bad = post(ada, "/api/operators",
                  {{"name", "x y"}, {"role", "viewer"}, {"password", "long-enough"}});
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(
      post(ada, "/api/operators", {{"name", "z"}, {"role", "boss"}, {"password", "p"}})->status,
      400);

  ASSERT_EQ(post(ada, "/api/operators", nick)->status, 201);
  EXPECT_EQ(post(ada, "/api/operators", nick)->status, 409) << "an existing name is not replaced";
  LoginResult n = stack_->login("nick", "nick-password-1");
  ASSERT_EQ(n.status, 200);
  const json listed =
      json::parse(stack_->client().Get("/api/operators", {{"Cookie", ada.cookie}})->body);
  bool found = false;
  for (const json& o : listed["operators"]) {
    if (o["name"] == "nick") {
      found = true;
      EXPECT_EQ(o["role"], "operator");
      EXPECT_EQ(o["sessions"], 1);
    }
  }
  EXPECT_TRUE(found) << listed.dump();

  // A password reset ends his session; the old password no longer works, the new one does.
  ASSERT_EQ(post(ada, "/api/operators/nick/password", {{"password", "nick-password-2"}})->status,
            200);
  EXPECT_EQ(stack_->client().Get("/api/session", {{"Cookie", n.cookie}})->status, 401);
  EXPECT_EQ(stack_->login("nick", "nick-password-1").status, 401);
  n = stack_->login("nick", "nick-password-2");
  ASSERT_EQ(n.status, 200);
  // Demoted to viewer: the session ends, and the next one is a viewer's.
  ASSERT_EQ(post(ada, "/api/operators/nick/role", {{"role", "viewer"}})->status, 200);
  EXPECT_EQ(stack_->client().Get("/api/session", {{"Cookie", n.cookie}})->status, 401);
  n = stack_->login("nick", "nick-password-2");
  EXPECT_EQ(json::parse(stack_->client().Get("/api/session", {{"Cookie", n.cookie}})->body)["role"],
            "viewer");
  // The last admin is kept: neither demoted nor removed.
  EXPECT_EQ(post(ada, "/api/operators/ada/role", {{"role", "viewer"}})->status, 409);
  EXPECT_EQ(post(ada, "/api/operators/ada/remove", json::object())->status, 409);
  EXPECT_EQ(post(ada, "/api/operators/ghost/remove", json::object())->status, 404);
  ASSERT_EQ(post(ada, "/api/operators/nick/remove", json::object())->status, 200);
  EXPECT_EQ(stack_->login("nick", "nick-password-2").status, 401);

  EXPECT_EQ(
      stack_->rows("SELECT operator, action, target, result FROM console_audit WHERE "
                   "target IN ('nick', '/api/operators') AND action LIKE 'operator_%' ORDER BY id"),
      (Rows{{"olga", "operator_add", "/api/operators", "forbidden"},
            {"ada", "operator_add", "/api/operators", "refused_csrf"},
            {"ada", "operator_add", "nick", "ok"},
            {"ada", "operator_add", "nick", "exists"},
            {"ada", "operator_password", "nick", "ok"},
            {"ada", "operator_role", "nick", "ok"},
            {"ada", "operator_remove", "nick", "ok"}}));
}

TEST_F(WebAccounts, ZoneUploadsAreRefusedWithTheFieldAndThePlace) {
  const LoginResult ada = stack_->login("ada", "admin-password");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto square = [](double lon, double lat) {
    return json::array({json::array({json::array({lon, lat}), json::array({lon + 0.01, lat}),
                                     json::array({lon + 0.01, lat + 0.01}),
                                     json::array({lon, lat + 0.01}), json::array({lon, lat})})});
  };
  auto feature = [](const std::string& id, const std::string& kind, const json& coords) {
    return json{{"type", "Feature"},
                {"properties", {{"id", id}, {"kind", kind}}},
                {"geometry", {{"type", "Polygon"}, {"coordinates", coords}}}};
  };
  json doc = {{"type", "FeatureCollection"},
              {"features", json::array({feature("a", "no_parking", square(11.5, 48.1)),
                                        feature("b", "no_ride", square(11.6, 48.1)),
                                        feature("c", "no_start", square(11.7, 48.1))})}};
  json line = json::array({json::array({json::array({11.5, 48.2}), json::array({11.51, 48.2}),
                                        json::array({11.5, 48.2}), json::array({11.51, 48.2})})});
  json broken = doc;
  broken["features"].push_back(feature("d", "no_ride", line));
  auto preview = post(ada, "/api/zones/preview", broken);
  ASSERT_TRUE(preview);
  EXPECT_EQ(preview->status, 400);
  EXPECT_EQ(json::parse(preview->body)["error"],
            "features[3].geometry.coordinates[0]: ring with 2 distinct points (at least 3 needed)");
  json slow = doc;
  slow["features"][1]["properties"]["kind"] = "slow";
  EXPECT_EQ(json::parse(post(ada, "/api/zones/preview", slow)->body)["error"],
            "features[1].properties.speed_limit_kmh: a slow zone needs a limit in 1..255 km/h");

  const auto good = post(ada, "/api/zones/preview", doc);
  ASSERT_EQ(good->status, 200) << good->body;
  const json p = json::parse(good->body);
  EXPECT_EQ(p["zones"], 3);
  EXPECT_EQ(p["geojson"]["features"][2]["properties"]["kind"], "no_start");
  EXPECT_EQ(post(olga, "/api/zones/preview", doc)->status, 403);
  json big = doc;
  big["comment"] = std::string(100 * 1024, 'x');
  EXPECT_EQ(post(ada, "/api/zones/preview", big)->status, 413) << "64 KiB by default";
  // Without --broker and --signing-key nothing can be signed: said so, audited.
  EXPECT_EQ(post(ada, "/api/zones/publish", doc)->status, 503);
  EXPECT_EQ(stack_->rows("SELECT result FROM console_audit WHERE action = 'zones_publish'"),
            (Rows{{"commands_off"}}));
}

// Issue 28's "a wrong password ten times is slowed": of ten wrong passwords in a row, three
// are judged (401) and the other seven refused unjudged (429 with a Retry-After).
TEST_F(WebAccounts, TenWrongPasswordsInARowAreSlowed) {
  ASSERT_EQ(stack_->add_operator("tina", "viewer", "tina-password"), 0);
  int judged = 0, slowed = 0;
  for (int i = 0; i < 10; ++i) {
    const LoginResult r = stack_->login("tina", "wrong-password");
    if (r.status == 401) ++judged;
    if (r.status == 429) {
      ++slowed;
      EXPECT_GE(std::stoi(r.retry_after.empty() ? "0" : r.retry_after), 1) << "attempt " << i;
    }
  }
  EXPECT_EQ(judged, 3);
  EXPECT_EQ(slowed, 7);
  EXPECT_EQ(stack_->login("tina", "tina-password").status, 429) << "even the right one waits";
}

// --root-key takes the base64 itself (which may hold '/') or a .pub file, repeatable; a key
// that is neither stops the server at start, naming it.
TEST(WebRootKeys, RootKeysAreBase64OrPubFilesAndABadOneStopsTheServer) {
  if (postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  const std::string slashes = "//////////////////////////////////////////8=";  // 32 bytes
  TempDir dir("fleetgw-root-keys");
  const auto pub = dir.path() / "root-b.pub";
  std::ofstream(pub) << "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA=\n";
  ServeStack stack({"--root-key", "root-a=" + slashes, "--root-key", "root-b=" + pub.string(),
                    "--max-body-kib", "256"});
  ASSERT_EQ(stack.add_operator("ada", "admin", "admin-password"), 0);
  const LoginResult ada = stack.login("ada", "admin-password");
  const auto r = stack.client().Get("/api/revocations", {{"Cookie", ada.cookie}});
  ASSERT_TRUE(r);
  EXPECT_EQ(json::parse(r->body)["roots"], json::array({"root-a", "root-b"})) << r->body;
  // --max-body-kib 256 takes a 100 KiB zone upload that the default 64 KiB refuses (413).
  const json big = {{"type", "FeatureCollection"},
                    {"features", json::array()},
                    {"comment", std::string(100 * 1024, 'x')}};
  const auto preview = stack.client().Post("/api/zones/preview",
                                           {{"Cookie", ada.cookie}, {"X-CSRF-Token", ada.csrf}},
                                           big.dump(), "application/json");
  ASSERT_TRUE(preview);
  EXPECT_EQ(preview->status, 200) << preview->body;
  try {
    ServeStack bad({"--root-key", "root-c=not-a-key"});
    ADD_FAILURE() << "a malformed --root-key was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("--root-key root-c"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fleetgw::testing
