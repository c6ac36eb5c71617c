// The vehicle registry (issue 27): the admin API (role, CSRF, audit) and the administration
// options of the real fleetgw-serve over PostgreSQL.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/web/registry_test_util.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;

class RegistryApi : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ =
        std::make_unique<ServeStack>(std::vector<std::string>{"--provider-id", kTestProviderId});
    ASSERT_EQ(stack_->add_operator("ada", "admin", "admin-password"), 0);
    ASSERT_EQ(stack_->add_operator("otto", "operator", "operator-password"), 0);
    admin_ = stack_->login("ada", "admin-password");
    op_ = stack_->login("otto", "operator-password");
    ASSERT_EQ(admin_.status, 200);
    ASSERT_EQ(op_.status, 200);
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  static httplib::Result post(const LoginResult& who, const std::string& path, const json& body,
                              bool with_csrf = true) {
    httplib::Headers h = {{"Cookie", who.cookie}};
    if (with_csrf) h.emplace("X-CSRF-Token", who.csrf);
    return stack_->client().Post(path, h, body.dump(), "application/json");
  }

  static std::unique_ptr<ServeStack> stack_;
  static LoginResult admin_;
  static LoginResult op_;
};
std::unique_ptr<ServeStack> RegistryApi::stack_;
LoginResult RegistryApi::admin_;
LoginResult RegistryApi::op_;

const json kType = {{"vehicle_type_id", "api-ebike"},
                    {"name", "API e-bike"},
                    {"form_factor", "bicycle"},
                    {"propulsion_type", "electric_assist"},
                    {"max_speed_kph", 25},
                    {"battery_capacity_wh", 540},
                    {"wh_per_km", 12.0}};

TEST_F(RegistryApi, AdminRegistersATypeAndAVehicleWithAGeneratedDeviceUuid) {
  auto r = post(admin_, "/api/registry/vehicle-types", kType);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  r = post(admin_, "/api/registry/vehicles",
           {{"vehicle_id", "api-bike-1"}, {"vehicle_type_id", "api-ebike"}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const json created = json::parse(r->body);
  EXPECT_TRUE(is_uuid_text(created["device_id"])) << created.dump();

  // Registering it again keeps its device UUID; another UUID for it is refused.
  r = post(admin_, "/api/registry/vehicles",
           {{"vehicle_id", "api-bike-1"}, {"vehicle_type_id", "api-ebike"}});
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(json::parse(r->body)["device_id"], created["device_id"]);
  r = post(admin_, "/api/registry/vehicles",
           {{"vehicle_id", "api-bike-1"},
            {"vehicle_type_id", "api-ebike"},
            {"device_id", "11111111-2222-4333-8444-555555555555"}});
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_NE(json::parse(r->body)["error"].get<std::string>().find("never changes"),
            std::string::npos);

  auto list = stack_->client().Get("/api/registry/vehicles", {{"Cookie", admin_.cookie}});
  ASSERT_EQ(list->status, 200);
  bool found = false;
  const json listed = json::parse(list->body);
  for (const json& v : listed["vehicles"]) {
    if (v["vehicle_id"] == "api-bike-1") {
      found = true;
      EXPECT_EQ(v["device_id"], created["device_id"]);
      EXPECT_EQ(v["provider_id"], kTestProviderId);  // the server's --provider-id
    }
  }
  EXPECT_TRUE(found) << list->body;
  // Audited, with the admin's name.
  const auto audit = stack_->rows(
      "SELECT operator, result FROM console_audit WHERE action = 'registry_vehicle' AND "
      "target = 'api-bike-1' ORDER BY id");
  ASSERT_GE(audit.size(), 3u);
  EXPECT_EQ(audit[0], (std::vector<std::string>{"ada", "ok"}));
  EXPECT_EQ(audit[2], (std::vector<std::string>{"ada", "bad_request"}));
}

TEST_F(RegistryApi, OperatorsAndRequestsWithoutCsrfAreRefused) {
  auto r = post(op_, "/api/registry/vehicle-types", kType);
  EXPECT_EQ(r->status, 403);
  r = post(admin_, "/api/registry/vehicle-types", kType, /*with_csrf=*/false);
  EXPECT_EQ(r->status, 403);
  EXPECT_EQ(stack_->client().Get("/api/registry/vehicles", {{"Cookie", op_.cookie}})->status, 403);
  EXPECT_EQ(stack_->client().Get("/api/registry/vehicles")->status, 401);
}

TEST_F(RegistryApi, BadInputIsRefusedNamingTheField) {
  json bad = kType;
  bad["propulsion_type"] = "jet";
  auto r = post(admin_, "/api/registry/vehicle-types", bad);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("propulsion_type"), std::string::npos) << r->body;
  bad = kType;
  bad.erase("wh_per_km");  // motorised without a range model: GBFS needs max_range_meters
  r = post(admin_, "/api/registry/vehicle-types", bad);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("wh_per_km"), std::string::npos) << r->body;
  r = post(admin_, "/api/registry/vehicles",
           {{"vehicle_id", "x"}, {"vehicle_type_id", "no-such-type"}});
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("no such vehicle type"), std::string::npos) << r->body;
}

TEST_F(RegistryApi, CommandLineImportsCsvAndNamesTheBadLine) {
  register_ebike_type(*stack_);
  const auto csv = stack_->dir() / "fleet.csv";
  std::ofstream(csv) << "vehicle_id,vehicle_type_id,device_id\n"
                        "csv-bike-1,ebike,\n"
                        "csv-bike-2,ebike,0b0e7c1a-9f57-4c50-8f3c-3f1f9d0c2a11\n";
  std::string out;
  ASSERT_EQ(serve_admin(*stack_, {"--import-registry", csv.string()}, &out), 0) << out;
  const auto rows = stack_->rows(
      "SELECT vehicle_id, device_id::text FROM registry_vehicles WHERE vehicle_id LIKE 'csv-%' "
      "ORDER BY vehicle_id");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1][1], "0b0e7c1a-9f57-4c50-8f3c-3f1f9d0c2a11");

  const auto bad = stack_->dir() / "bad-types.csv";
  std::ofstream(bad) << "vehicle_type_id,form_factor,propulsion_type\nok,bicycle,human\n"
                        "broken,hoverboard,human\n";
  EXPECT_EQ(serve_admin(*stack_, {"--import-vehicle-types", bad.string()}, &out), 2);
  EXPECT_NE(out.find("bad-types.csv line 3: form_factor 'hoverboard'"), std::string::npos) << out;
}

TEST_F(RegistryApi, AgencyTokenIsPrintedOnceAndStoredHashed) {
  std::string out;
  ASSERT_EQ(serve_admin(*stack_, {"--add-mds-agency", "city-of-test"}, &out), 0) << out;
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  const std::string token = out.substr(out.rfind('\n') + 1);
  ASSERT_GE(token.size(), 40u);
  const auto stored =
      stack_->rows("SELECT token_sha256 FROM mds_agencies WHERE agency = 'city-of-test'");
  ASSERT_EQ(stored.size(), 1u);
  EXPECT_EQ(stored[0][0].size(), 64u);
  EXPECT_EQ(stored[0][0].find(token), std::string::npos);
}

}  // namespace
}  // namespace fleetgw::testing
