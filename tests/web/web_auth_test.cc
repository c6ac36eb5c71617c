// `fleetgw serve` (issue 28): operators, logins, sessions, CSRF, roles and the audit trail,
// against the real fleetgw-serve program over a private PostgreSQL.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "backend/web/secrets.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;

class WebAuth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ = std::make_unique<ServeStack>();
    ASSERT_EQ(stack_->add_operator("olga", "operator", "operator-password"), 0);
    ASSERT_EQ(stack_->add_operator("vera", "viewer", "viewer-password"), 0);
    ASSERT_EQ(stack_->add_operator("tom", "operator", "throttled-password"), 0);
    stack_->insert_vehicle({.id = "auth-bike", .lat = 48.1, .lon = 11.5});
    stack_->insert_alarm("auth-bike", 1, "ALARM_KIND_LOCK_FORCED", "ALARM_TRANSITION_RAISED",
                         now_us());
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  // POST /api/alarms/<the auth-bike alarm>/ack with the given cookie and headers.
  static httplib::Result ack(const std::string& cookie, const std::string& csrf,
                             const std::string& origin = "") {
    httplib::Headers h = {{"Cookie", cookie}};
    if (!csrf.empty()) h.emplace("X-CSRF-Token", csrf);
    if (!origin.empty()) h.emplace("Origin", origin);
    const std::string id = "617574682d62696b65.73746f72652d31.1";  // hex ids, sequence 1
    return stack_->client().Post("/api/alarms/" + id + "/ack", h, "", "application/json");
  }

  static std::string last_audit_result(const std::string& action) {
    auto r = stack_->rows(
        "SELECT result FROM console_audit WHERE action = $1 ORDER BY id DESC LIMIT 1", {action});
    return r.empty() ? "" : r[0][0];
  }

  static std::unique_ptr<ServeStack> stack_;
};
std::unique_ptr<ServeStack> WebAuth::stack_;

TEST_F(WebAuth, LoginSetsAnHttpOnlySameSiteStrictCookieStoredOnlyHashed) {
  const LoginResult l = stack_->login("olga", "operator-password");
  ASSERT_EQ(l.status, 200) << stack_->log();
  EXPECT_NE(l.set_cookie.find("HttpOnly"), std::string::npos) << l.set_cookie;
  EXPECT_NE(l.set_cookie.find("SameSite=Strict"), std::string::npos) << l.set_cookie;
  EXPECT_NE(l.set_cookie.find("Path=/"), std::string::npos) << l.set_cookie;
  // Plain HTTP on loopback: a Secure cookie would never come back.
  EXPECT_EQ(l.set_cookie.find("Secure"), std::string::npos) << l.set_cookie;
  const std::string id = l.cookie.substr(l.cookie.find('=') + 1);
  EXPECT_GE(id.size(), 43u);  // 256 random bits, base64url
  EXPECT_TRUE(
      stack_->rows("SELECT 1 FROM console_sessions WHERE id_sha256 = $1 OR csrf_token = $1", {id})
          .empty());
  EXPECT_EQ(stack_->rows("SELECT operator FROM console_sessions WHERE id_sha256 = $1",
                         {web::sha256_hex(id)}),
            (std::vector<std::vector<std::string>>{{"olga"}}));
  // The password is stored as Argon2id, never as itself.
  const auto hash = stack_->rows("SELECT password_hash FROM console_operators WHERE name = 'olga'");
  ASSERT_EQ(hash.size(), 1u);
  EXPECT_EQ(hash[0][0].rfind("$argon2id$", 0), 0u) << hash[0][0];

  auto res = stack_->client().Get("/api/session", {{"Cookie", l.cookie}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(json::parse(res->body)["role"], "operator");
  EXPECT_EQ(last_audit_result("login"), "ok");
}

TEST_F(WebAuth, WrongPasswordsAreSlowedAndThenEvenTheRightOneWaits) {
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(stack_->login("tom", "not-the-password").status, 401) << "attempt " << i;
  }
  // The fourth comes within a second of the third failure: refused without a look at it.
  const LoginResult slowed = stack_->login("tom", "not-the-password");
  EXPECT_EQ(slowed.status, 429);
  EXPECT_GE(std::stoi(slowed.retry_after.empty() ? "0" : slowed.retry_after), 1);
  EXPECT_EQ(stack_->login("tom", "throttled-password").status, 429);
  EXPECT_EQ(last_audit_result("login"), "throttled");
  // Ten more tries do not get through either, and the delay grows.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(stack_->login("tom", "guess").status, 429);
}

TEST_F(WebAuth, UnknownAccountAnswersLikeAWrongPassword) {
  const LoginResult l = stack_->login("nobody-here", "whatever-password");
  EXPECT_EQ(l.status, 401);
  EXPECT_EQ(last_audit_result("login"), "bad_credentials");
}

TEST_F(WebAuth, EveryApiReadNeedsASession) {
  for (const char* path :
       {"/api/fleet", "/api/alarms", "/api/vehicles/auth-bike", "/api/events", "/api/session"}) {
    auto res = stack_->client().Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 401) << path;
  }
  auto res = stack_->client().Get("/api/fleet", {{"Cookie", "fleet_session=forged-id"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 401);
}

TEST_F(WebAuth, ViewerGets403OnAStateChangeAndItIsAudited) {
  const LoginResult v = stack_->login("vera", "viewer-password");
  ASSERT_EQ(v.status, 200);
  auto res = ack(v.cookie, v.csrf);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403) << res->body;
  EXPECT_EQ(last_audit_result("alarm_ack"), "forbidden");
  EXPECT_TRUE(stack_->rows("SELECT 1 FROM console_alarm_acks WHERE acked_by = 'vera'").empty());
  // Reading is what a viewer may do.
  auto read = stack_->client().Get("/api/alarms", {{"Cookie", v.cookie}});
  ASSERT_TRUE(read);
  EXPECT_EQ(read->status, 200);
}

TEST_F(WebAuth, StateChangesWithoutTheCsrfTokenOrFromAnotherOriginAreRefused) {
  const LoginResult o = stack_->login("olga", "operator-password");
  ASSERT_EQ(o.status, 200);
  auto missing = ack(o.cookie, "");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 403);
  EXPECT_EQ(last_audit_result("alarm_ack"), "refused_csrf");
  auto wrong = ack(o.cookie, o.csrf.substr(1) + "x");
  ASSERT_TRUE(wrong);
  EXPECT_EQ(wrong->status, 403);
  auto foreign = ack(o.cookie, o.csrf, "https://evil.example");
  ASSERT_TRUE(foreign);
  EXPECT_EQ(foreign->status, 403);
  EXPECT_EQ(last_audit_result("alarm_ack"), "refused_origin");
  EXPECT_TRUE(stack_->rows("SELECT 1 FROM console_alarm_acks").empty());

  auto good = ack(o.cookie, o.csrf, stack_->url());
  ASSERT_TRUE(good);
  EXPECT_EQ(good->status, 200) << good->body;
  EXPECT_EQ(last_audit_result("alarm_ack"), "ok");
  const auto audit = stack_->rows(
      "SELECT operator, address, target FROM console_audit WHERE action = 'alarm_ack' AND "
      "result = 'ok'");
  ASSERT_EQ(audit.size(), 1u);
  EXPECT_EQ(audit[0], (std::vector<std::string>{"olga", "127.0.0.1", "auth-bike/store-1/1"}));
}

TEST_F(WebAuth, LogoutEndsTheSessionOnTheServer) {
  const LoginResult o = stack_->login("olga", "operator-password");
  ASSERT_EQ(o.status, 200);
  auto out = stack_->client().Post("/api/logout", {{"Cookie", o.cookie}, {"X-CSRF-Token", o.csrf}},
                                   "", "application/json");
  ASSERT_TRUE(out);
  EXPECT_EQ(out->status, 200);
  EXPECT_NE(out->get_header_value("Set-Cookie").find("Max-Age=0"), std::string::npos);
  // A copy of the old cookie is worth nothing now.
  auto res = stack_->client().Get("/api/fleet", {{"Cookie", o.cookie}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 401);
}

TEST_F(WebAuth, LoginAcceptsOnlyJsonSoACrossSiteFormCannotPostIt) {
  auto res = stack_->client().Post("/api/login", "name=olga&password=operator-password",
                                   "application/x-www-form-urlencoded");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 415);
}

TEST_F(WebAuth, OnlyAnAdminReadsTheAuditTrail) {
  ASSERT_EQ(stack_->add_operator("ada", "admin", "admin-password"), 0);
  const LoginResult o = stack_->login("olga", "operator-password");
  ASSERT_EQ(o.status, 200);
  auto refused = stack_->client().Get("/api/audit", {{"Cookie", o.cookie}});
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 403);
  const LoginResult a = stack_->login("ada", "admin-password");
  ASSERT_EQ(a.status, 200);
  auto res = stack_->client().Get("/api/audit", {{"Cookie", a.cookie}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  const json audit = json::parse(res->body)["audit"];
  ASSERT_FALSE(audit.empty());
  EXPECT_EQ(audit[0]["action"], "login");  // newest first: ada's own login
  EXPECT_EQ(audit[0]["operator"], "ada");
  EXPECT_EQ(audit[0]["address"], "127.0.0.1");
}

TEST_F(WebAuth, AddOperatorRefusesAShortPasswordAndABadRole) {
  EXPECT_EQ(stack_->add_operator("shorty", "viewer", "short"), 2);
  EXPECT_NE(stack_->add_operator("badrole", "root", "long-enough-password"), 0);
  EXPECT_TRUE(
      stack_->rows("SELECT 1 FROM console_operators WHERE name IN ('shorty', 'badrole')").empty());
}

}  // namespace
}  // namespace fleetgw::testing
