// Commands from the console (issue 28), against the real fleetgw-serve, a real mosquitto and a
// private PostgreSQL: what the server publishes is a SignedCommand whose signature verifies
// over exactly the Command bytes and names the operator; only a result bound to those bytes is
// stored; roles, CSRF, the delegation's scope and API tokens are enforced before anything is
// published. The bike side is played by a raw MQTT client here (web_command_e2e_test.cc runs
// a real `fleetgw run`).
#include <gtest/gtest.h>

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

class WebCommands : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    broker_ = std::make_unique<MosquittoBroker>();
    broker_->start();
    keys_ = std::make_unique<TempDir>("fleetgw-web-keys");
    make_key(keys_->path() / "console-1.pem", fs::perms::owner_read | fs::perms::owner_write);
    stack_ = std::make_unique<ServeStack>(std::vector<std::string>{
        "--broker", broker_->uri(), "--signing-key", (keys_->path() / "console-1.pem").string()});
    ASSERT_EQ(stack_->add_operator("olga", "operator", "operator-password"), 0);
    ASSERT_EQ(stack_->add_operator("vera", "viewer", "viewer-password"), 0);
    ASSERT_EQ(stack_->add_operator("ada", "admin", "admin-password"), 0);
    for (const char* v : {"bike-1", "bike-2", "bike-3"}) {
      stack_->insert_vehicle({.id = v, .lat = 48.1, .lon = 11.5});
    }
  }
  static void TearDownTestSuite() {
    stack_.reset();
    broker_.reset();
    keys_.reset();
  }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  static httplib::Result post(const LoginResult& l, const std::string& path, const json& body,
                              bool csrf = true) {
    httplib::Headers h = {{"Cookie", l.cookie}};
    if (csrf) h.emplace("X-CSRF-Token", l.csrf);
    return stack_->client().Post(path, h, body.dump(), "application/json");
  }
  static json command(const LoginResult& l, const std::string& id) {
    auto res = stack_->client().Get("/api/commands?ids=" + id, {{"Cookie", l.cookie}});
    if (!res || res->status != 200) return nullptr;
    const json j = json::parse(res->body);
    return j["commands"].empty() ? json(nullptr) : j["commands"][0];
  }
  // The SignedCommand published for `command_id` on `client`, or "" when none arrived.
  static std::string published(TopicClient& client, const std::string& command_id) {
    std::string found;
    wait_until(
        [&] {
          for (const auto& [topic, payload] : client.messages()) {
            v1::SignedCommand sc;
            v1::Command c;
            if (sc.ParseFromString(payload) && c.ParseFromString(sc.command()) &&
                c.command_id() == command_id) {
              found = payload;
              return true;
            }
          }
          return false;
        },
        10s);
    return found;
  }

  static std::unique_ptr<MosquittoBroker> broker_;
  static std::unique_ptr<TempDir> keys_;
  static std::unique_ptr<ServeStack> stack_;
};
std::unique_ptr<MosquittoBroker> WebCommands::broker_;
std::unique_ptr<TempDir> WebCommands::keys_;
std::unique_ptr<ServeStack> WebCommands::stack_;

TEST_F(WebCommands, LockIsSignedOverItsExactBytesNamesTheOperatorAndItsResultIsStored) {
  TopicClient bike(broker_->uri(), "fleet/v1/bike-1/cmd");
  const LoginResult olga = stack_->login("olga", "operator-password");
  ASSERT_EQ(olga.status, 200);
  auto res = post(olga, "/api/vehicles/bike-1/commands", {{"action", "lock"}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 202) << res->body << stack_->log();
  const std::string id = json::parse(res->body)["command_id"];

  const std::string payload = published(bike, id);
  ASSERT_FALSE(payload.empty()) << stack_->log();
  v1::SignedCommand sc;
  ASSERT_TRUE(sc.ParseFromString(payload));
  EXPECT_EQ(sc.key_id(), "console-1");
  EXPECT_FALSE(sc.has_delegation());
  EXPECT_TRUE(
      ed25519_verifies(public_key(keys_->path() / "console-1.pem"), sc.command(), sc.signature()));
  v1::Command c;
  ASSERT_TRUE(c.ParseFromString(sc.command()));
  EXPECT_EQ(c.vehicle_id(), "bike-1");
  EXPECT_EQ(c.operator_id(), "olga");
  EXPECT_EQ(c.action(), v1::COMMAND_ACTION_LOCK);
  EXPECT_TRUE(c.whole_vehicle());
  EXPECT_GT(c.expires_at_us(), c.issued_at_us());
  EXPECT_LE(c.expires_at_us() - c.issued_at_us(), 60'000'000);
  EXPECT_TRUE(command(olga, id)["result"].is_null());

  // A result with the right id but not bound to these bytes (a forger's) is ignored; the
  // bike's own is stored, with its reason, and the audit names who, what, from where.
  v1::Envelope forged;
  forged.ParseFromString(
      result_envelope("bike-1", payload, v1::COMMAND_RESULT_CODE_FAILED, "forged", false));
  forged.mutable_command_result()->set_command_sha256(std::string(32, 'x'));
  bike.publish("fleet/v1/bike-1/cmd/result", forged.SerializeAsString());
  bike.publish("fleet/v1/bike-1/cmd/result",
               result_envelope("bike-1", payload, v1::COMMAND_RESULT_CODE_SUCCEEDED, ""));
  ASSERT_TRUE(wait_until([&] { return command(olga, id)["result"] == "succeeded"; }, 10s))
      << command(olga, id).dump() << stack_->log();
  EXPECT_EQ(command(olga, id)["operator"], "olga");
  EXPECT_EQ(command(olga, id)["result_operator"], "olga");
  EXPECT_EQ(
      stack_->rows("SELECT operator, address, result, target FROM console_audit WHERE "
                   "action = 'command' AND target = $1",
                   {"bike-1/" + id}),
      (std::vector<std::vector<std::string>>{{"olga", "127.0.0.1", "published", "bike-1/" + id}}));
  // The result's audit row follows the stored result (another connection): wait for it.
  const auto audited = [&] {
    return stack_->rows(
        "SELECT result FROM console_audit WHERE action = 'command_result' AND "
        "target = $1",
        {"bike-1/" + id});
  };
  EXPECT_TRUE(wait_until([&] { return !audited().empty(); }, 10s));
  EXPECT_EQ(audited(), (std::vector<std::vector<std::string>>{{"succeeded"}}));
}

TEST_F(WebCommands, TheBikesRefusalReasonIsShownAsItCame) {
  TopicClient bike(broker_->uri(), "fleet/v1/bike-2/cmd");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto res = post(olga, "/api/vehicles/bike-2/commands", {{"action", "speed_limit"}, {"kmh", 15}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 202) << res->body;
  const std::string id = json::parse(res->body)["command_id"];
  const std::string payload = published(bike, id);
  ASSERT_FALSE(payload.empty());
  v1::Command c;
  v1::SignedCommand sc;
  sc.ParseFromString(payload);
  c.ParseFromString(sc.command());
  EXPECT_EQ(c.speed_limit().kmh(), 15u);
  bike.publish("fleet/v1/bike-2/cmd/result",
               result_envelope("bike-2", payload, v1::COMMAND_RESULT_CODE_REJECTED,
                               "revoked: delegation 7 of key 'console-1' is revoked"));
  ASSERT_TRUE(wait_until([&] { return command(olga, id)["result"] == "rejected"; }, 10s));
  EXPECT_EQ(command(olga, id)["reason"], "revoked: delegation 7 of key 'console-1' is revoked");
}

// A bike that cannot authenticate the payload (e.g. it does not know the key) answers bound to
// the whole payload's digest, possibly without a command id: the console still shows it.
TEST_F(WebCommands, ARefusalBoundToThePayloadIsShownToo) {
  TopicClient bike(broker_->uri(), "fleet/v1/bike-3/cmd");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto res = post(olga, "/api/vehicles/bike-3/commands", {{"action", "clear_trip"}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 202) << res->body;
  const std::string id = json::parse(res->body)["command_id"];
  const std::string payload = published(bike, id);
  ASSERT_FALSE(payload.empty());
  v1::Envelope env;
  env.set_vehicle_id("bike-3");
  auto* r = env.mutable_command_result();
  r->set_result(v1::COMMAND_RESULT_CODE_REJECTED);
  r->set_reason("unknown_key: console-1");
  r->set_payload_sha256(sha256_raw(payload + "x"));  // another payload's: ignored
  bike.publish("fleet/v1/bike-3/cmd/result", env.SerializeAsString());
  r->set_payload_sha256(sha256_raw(payload));
  bike.publish("fleet/v1/bike-3/cmd/result", env.SerializeAsString());
  ASSERT_TRUE(wait_until([&] { return command(olga, id)["result"] == "rejected"; }, 10s))
      << command(olga, id).dump();
  EXPECT_EQ(command(olga, id)["reason"], "unknown_key: console-1");
}

TEST_F(WebCommands, ViewerGets403AndNothingIsPublished) {
  TopicClient bike(broker_->uri(), "fleet/v1/+/cmd");
  const LoginResult vera = stack_->login("vera", "viewer-password");
  auto res = post(vera, "/api/vehicles/bike-3/commands", {{"action", "unlock"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403);
  auto bulk = post(vera, "/api/commands", {{"vehicles", {"bike-3"}}, {"action", "unlock"}});
  ASSERT_TRUE(bulk);
  EXPECT_EQ(bulk->status, 403);
  EXPECT_EQ(stack_->rows("SELECT count(*) FROM console_commands WHERE operator = 'vera'"),
            (std::vector<std::vector<std::string>>{{"0"}}));
  EXPECT_EQ(stack_->rows("SELECT result FROM console_audit WHERE operator = 'vera' AND "
                         "action = 'command' ORDER BY id"),
            (std::vector<std::vector<std::string>>{{"forbidden"}, {"forbidden"}}));
  EXPECT_TRUE(bike.messages().empty());
}

TEST_F(WebCommands, WithoutTheCsrfTokenNothingIsPublished) {
  TopicClient bike(broker_->uri(), "fleet/v1/+/cmd");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto res = post(olga, "/api/vehicles/bike-3/commands", {{"action", "unlock"}}, false);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403);
  EXPECT_NE(res->body.find("CSRF"), std::string::npos) << res->body;
  EXPECT_EQ(stack_->rows("SELECT count(*) FROM console_commands WHERE vehicle_id = 'bike-3' "
                         "AND action = 'unlock'"),
            (std::vector<std::vector<std::string>>{{"0"}}));
  EXPECT_TRUE(bike.messages().empty());
}

TEST_F(WebCommands, BadRequestsAndUnknownVehiclesAreRefusedWithTheReason) {
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto bad = post(olga, "/api/vehicles/bike-1/commands", {{"action", "speed_limit"}, {"kmh", 0}});
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  EXPECT_NE(bad->body.find("1..255"), std::string::npos) << bad->body;
  auto nobody = post(olga, "/api/vehicles/ghost/commands", {{"action", "lock"}});
  ASSERT_TRUE(nobody);
  EXPECT_EQ(nobody->status, 404);
  auto wildcard = post(olga, "/api/vehicles/%2B/commands", {{"action", "lock"}});
  ASSERT_TRUE(wildcard);
  EXPECT_EQ(wildcard->status, 400);
}

TEST_F(WebCommands, SeveralBikesAtOnceGetOneSignedCommandEach) {
  TopicClient bikes(broker_->uri(), "fleet/v1/+/cmd");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto res = post(
      olga, "/api/commands",
      {{"vehicles", {"bike-1", "bike-2", "ghost"}}, {"action", "lock"}, {"lock_kind", "battery"}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json j = json::parse(res->body);
  EXPECT_EQ(j["published"], 2);
  ASSERT_EQ(j["commands"].size(), 3u);
  EXPECT_EQ(j["commands"][2]["status"], 404);
  for (int i = 0; i < 2; ++i) {
    const std::string payload = published(bikes, j["commands"][i]["command_id"]);
    ASSERT_FALSE(payload.empty()) << i;
    v1::SignedCommand sc;
    v1::Command c;
    sc.ParseFromString(payload);
    c.ParseFromString(sc.command());
    EXPECT_EQ(c.vehicle_id(), j["commands"][i]["vehicle_id"]);
    EXPECT_EQ(c.lock_kind(), "battery");
  }
  auto batch = stack_->client().Get("/api/commands?batch=" + j["batch_id"].get<std::string>(),
                                    {{"Cookie", olga.cookie}});
  ASSERT_TRUE(batch);
  EXPECT_EQ(json::parse(batch->body)["commands"].size(), 2u);
}

TEST_F(WebCommands, ApiTokensAreShownOnceRoleScopedAndRevocable) {
  const LoginResult ada = stack_->login("ada", "admin-password");
  auto made = post(ada, "/api/tokens", {{"name", "dispatch-bot"}, {"role", "operator"}});
  ASSERT_TRUE(made);
  ASSERT_EQ(made->status, 201) << made->body;
  const std::string token = json::parse(made->body)["token"];
  const std::int64_t token_id = json::parse(made->body)["id"];
  EXPECT_EQ(stack_->rows("SELECT count(*) FROM console_api_tokens WHERE token_sha256 = $1 OR "
                         "strpos(token_sha256, $1) > 0",
                         {token}),
            (std::vector<std::vector<std::string>>{{"0"}}))
      << "only the hash is stored";
  const httplib::Headers bearer = {{"Authorization", "Bearer " + token}};
  auto fleet = stack_->client().Get("/api/fleet", bearer);
  ASSERT_TRUE(fleet);
  EXPECT_EQ(fleet->status, 200);
  // An operator token sends commands (no cookie, so no CSRF token needed) but is no admin.
  auto cmd = stack_->client().Post("/api/vehicles/bike-1/commands", bearer,
                                   json{{"action", "lock"}}.dump(), "application/json");
  ASSERT_TRUE(cmd);
  EXPECT_EQ(cmd->status, 202) << cmd->body;
  auto audit = stack_->client().Get("/api/audit", bearer);
  ASSERT_TRUE(audit);
  EXPECT_EQ(audit->status, 403);
  auto listed = stack_->client().Get("/api/tokens", {{"Cookie", ada.cookie}});
  ASSERT_TRUE(listed);
  EXPECT_EQ(listed->body.find(token), std::string::npos);
  auto revoked = post(ada, "/api/tokens/" + std::to_string(token_id) + "/revoke", json::object());
  ASSERT_TRUE(revoked);
  EXPECT_EQ(revoked->status, 200);
  auto after = stack_->client().Get("/api/fleet", bearer);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->status, 401);
  // An operator cannot make tokens.
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto denied = post(olga, "/api/tokens", {{"name", "x"}, {"role", "admin"}});
  ASSERT_TRUE(denied);
  EXPECT_EQ(denied->status, 403);
}

TEST_F(WebCommands, AnAlarmIsResolvedWithWhoAndWhenAndStopsBeingActive) {
  stack_->insert_alarm("bike-3", 41, "ALARM_KIND_UNAUTHORISED_MOVEMENT", "ALARM_TRANSITION_RAISED",
                       now_us());
  const LoginResult olga = stack_->login("olga", "operator-password");
  const std::string id = "62696b652d33.73746f72652d31.41";  // hex "bike-3", "store-1"
  auto res = post(olga, "/api/alarms/" + id + "/resolve", {{"note", "found in the depot"}});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  auto alarms = stack_->client().Get("/api/alarms", {{"Cookie", olga.cookie}});
  bool seen = false;
  const json listed = json::parse(alarms->body);
  for (const json& a : listed["alarms"]) {
    if (a["id"] != id) continue;
    seen = true;
    EXPECT_EQ(a["resolved_by"], "olga");
    EXPECT_TRUE(a["resolved_at_us"].is_number());
    EXPECT_FALSE(a["active"]);
  }
  EXPECT_TRUE(seen) << alarms->body;
  const LoginResult vera = stack_->login("vera", "viewer-password");
  auto denied = post(vera, "/api/alarms/" + id + "/resolve", json::object());
  EXPECT_EQ(denied->status, 403);
}

// The vehicle page shows what the bike reports of itself (the ingest's migration 4 columns) and
// the console's commands with who sent each.
TEST_F(WebCommands, TheVehiclePageCarriesTheReportedStateAndWhoSentEachCommand) {
  stack_->db().exec(
      "UPDATE vehicle_state SET speed_limit_dkmh = 150, assist_name = 'eco', bus_state = "
      "'BUS_STATE_ACTIVE', active_alarms = '{ALARM_KIND_LOCK_FORCED}', locks = "
      "'[{\"node\": \"lock1\", \"kind\": \"seat\", \"state_name\": \"locked\"}]', "
      "faults = '[{\"node\": \"mc\", \"name\": \"<b>hall</b>\"}]' "
      "WHERE vehicle_id = 'bike-2'",
      "reported state");
  const LoginResult olga = stack_->login("olga", "operator-password");
  auto sent = post(olga, "/api/vehicles/bike-2/commands", {{"action", "headlight"}, {"on", true}});
  ASSERT_TRUE(sent);
  ASSERT_EQ(sent->status, 202);
  auto res = stack_->client().Get("/api/vehicles/bike-2", {{"Cookie", olga.cookie}});
  ASSERT_TRUE(res);
  const json v = json::parse(res->body);
  EXPECT_EQ(v["reported"]["speed_limit_dkmh"], 150);
  EXPECT_EQ(v["reported"]["assist_name"], "eco");
  EXPECT_EQ(v["reported"]["locks"][0]["state_name"], "locked");
  EXPECT_EQ(v["reported"]["faults"][0]["name"], "<b>hall</b>");
  EXPECT_EQ(v["reported"]["active_alarms"], json({"ALARM_KIND_LOCK_FORCED"}));
  ASSERT_FALSE(v["console_commands"].empty());
  EXPECT_EQ(v["console_commands"][0]["operator"], "olga");
  EXPECT_EQ(v["console_commands"][0]["params"], "headlight on");
}

TEST_F(WebCommands, ASigningKeyOthersCanReadIsRefusedAtStart) {
  const fs::path loose = keys_->path() / "loose.pem";
  make_key(loose, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                      fs::perms::others_read);
  const fs::path out = keys_->path() / "loose.log";
  const int rc = run_for_exit_code(
      {FLEETGW_SERVE_BINARY, "--pg", stack_->conninfo(), "--listen", "127.0.0.1:0", "--broker",
       broker_->uri(), "--signing-key", loose.string()},
      out);
  EXPECT_EQ(rc, 1);
  EXPECT_NE(read_text_file(out).find("readable or writable by its group or others"),
            std::string::npos)
      << read_text_file(out);
}

}  // namespace
}  // namespace fleetgw::testing
