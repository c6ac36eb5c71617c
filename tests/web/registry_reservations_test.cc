// Vehicle reservations (issue 27, registry_reservations.h) through the real fleetgw-serve and
// PostgreSQL: the operator API (role, CSRF, bounds, audit, one reservation per vehicle, none on
// a bike that is being ridden), GBFS `is_reserved` (the reserved bike stays listed, flagged),
// and MDS's `reserved` state with reservation_start / reservation_cancel -- a cancelled or
// expired reservation goes back to available, a trip started by the rider who held it goes
// reserved -> on_trip.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/support/wait.h"
#include "tests/web/gbfs_spec_check.h"
#include "tests/web/mds_spec_check.h"
#include "tests/web/registry_test_util.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

class Reservations : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ =
        std::make_unique<ServeStack>(std::vector<std::string>{"--provider-id", kTestProviderId});
    ASSERT_EQ(stack_->add_operator("rosa", "operator", "operator-password"), 0);
    ASSERT_EQ(stack_->add_operator("vic", "viewer", "viewer-password"), 0);
    register_ebike_type(*stack_);
    for (const char* id : {"res-cancel", "res-trip", "res-riding", "res-expire"}) {
      register_vehicle(*stack_, id);
    }
    stack_->insert_vehicle({.id = "res-cancel", .lat = 48.40, .lon = 11.40});
    stack_->insert_vehicle({.id = "res-trip", .lat = 48.41, .lon = 11.41});
    stack_->insert_vehicle({.id = "res-expire", .lat = 48.43, .lon = 11.43});
    stack_->insert_vehicle(
        {.id = "res-riding", .lat = 48.42, .lon = 11.42, .mode = "VEHICLE_MODE_RIDING"});
    std::string out;
    ASSERT_EQ(serve_admin(*stack_, {"--add-mds-agency", "res-city"}, &out), 0) << out;
    while (!out.empty() && out.back() == '\n') out.pop_back();
    token_ = out.substr(out.rfind('\n') + 1);
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
    rosa_ = stack_->login("rosa", "operator-password");
    ASSERT_EQ(rosa_.status, 200);
  }

  httplib::Result reserve(const std::string& vehicle, const std::string& body,
                          const LoginResult& who, bool csrf = true) {
    httplib::Headers h = {{"Cookie", who.cookie}};
    if (csrf) h.emplace("X-CSRF-Token", who.csrf);
    return stack_->client().Post("/api/vehicles/" + vehicle + "/reservation", h, body,
                                 "application/json");
  }
  httplib::Result cancel(const std::string& vehicle) {
    return stack_->client().Delete("/api/vehicles/" + vehicle + "/reservation",
                                   {{"Cookie", rosa_.cookie}, {"X-CSRF-Token", rosa_.csrf}});
  }

  // The vehicle at (lat, lon) in a vehicle_status checked against the specification.
  static json gbfs_vehicle_at(double lat, double lon) {
    auto res = stack_->client().Get("/gbfs/vehicle_status.json");
    EXPECT_TRUE(res && res->status == 200);
    if (!res) return nullptr;
    const json doc = json::parse(res->body);
    gbfs_spec::TypeTable types;
    gbfs_spec::check_vehicle_types(
        json::parse(stack_->client().Get("/gbfs/vehicle_types.json")->body), &types);
    const gbfs_spec::Problems p = gbfs_spec::check_vehicle_status(doc, types);
    EXPECT_TRUE(p.empty()) << gbfs_spec::join(p);
    for (const json& v : doc["data"]["vehicles"]) {
      if (std::abs(v["lat"].get<double>() - lat) < 1e-6 &&
          std::abs(v["lon"].get<double>() - lon) < 1e-6) {
        return v;
      }
    }
    return nullptr;
  }
  // Waits (the feed is rebuilt at most once a second) for the listed vehicle's is_reserved.
  static bool gbfs_reserved_becomes(double lat, double lon, bool reserved) {
    return wait_until(
        [&] {
          const json v = gbfs_vehicle_at(lat, lon);
          return !v.is_null() && v["is_reserved"] == reserved;
        },
        10s);
  }
  static json mds_status(const std::string& vehicle) {
    const std::string device = stack_->rows(
        "SELECT device_id::text FROM registry_vehicles WHERE vehicle_id = $1", {vehicle})[0][0];
    auto res = mds_get(*stack_, "/mds/vehicles/status/" + device, token_);
    EXPECT_TRUE(res && res->status == 200);
    if (!res) return nullptr;
    const json body = json::parse(res->body);
    const mds_spec::Problems p = mds_spec::check_payload(
        body, "vehicles_status", true,
        [](const json& s, const std::string& at) { return mds_spec::check_vehicle_status(s, at); });
    EXPECT_TRUE(p.empty()) << res->body << mds_spec::join(p);
    return body["vehicles_status"].empty() ? json(nullptr) : body["vehicles_status"][0];
  }
  // The vehicle's events of the last minutes through events/recent, "state:type+type".
  static std::vector<std::string> recent_events(const std::string& vehicle, std::int64_t from_us) {
    const std::string device = stack_->rows(
        "SELECT device_id::text FROM registry_vehicles WHERE vehicle_id = $1", {vehicle})[0][0];
    auto res = mds_get(*stack_,
                       "/mds/events/recent?start_time=" + std::to_string(from_us / 1000) +
                           "&end_time=" + std::to_string(now_us() / 1000),
                       token_);
    EXPECT_TRUE(res && res->status == 200) << (res ? res->body : "");
    if (!res) return {};
    const json body = json::parse(res->body);
    const mds_spec::Problems p = mds_spec::check_payload(
        body, "events", false,
        [](const json& e, const std::string& at) { return mds_spec::check_event(e, at); });
    EXPECT_TRUE(p.empty()) << res->body << mds_spec::join(p);
    std::vector<std::string> out;
    for (const json& e : body["events"]) {
      if (e["device_id"] != device) continue;
      std::string types;
      for (const json& t : e["event_types"])
        types += (types.empty() ? "" : "+") + t.get<std::string>();
      out.push_back(e["vehicle_state"].get<std::string>() + ":" + types);
    }
    return out;
  }

  static std::unique_ptr<ServeStack> stack_;
  static std::string token_;
  LoginResult rosa_;
};
std::unique_ptr<ServeStack> Reservations::stack_;
std::string Reservations::token_;

TEST_F(Reservations, AnOperatorReservesAndCancelsAndGbfsAndMdsFollow) {
  const std::int64_t t0 = now_us() - 1000;
  // Who and how: a viewer may not, a request without the CSRF token may not.
  const LoginResult vic = stack_->login("vic", "viewer-password");
  EXPECT_EQ(reserve("res-cancel", "{}", vic)->status, 403);
  EXPECT_EQ(reserve("res-cancel", "{}", rosa_, false)->status, 403);
  auto bad = reserve("res-cancel", R"({"expires_in_s": 30})", rosa_);
  EXPECT_EQ(bad->status, 400);
  EXPECT_NE(bad->body.find("expires_in_s"), std::string::npos) << bad->body;
  EXPECT_EQ(reserve("no-such-bike", "{}", rosa_)->status, 404);
  EXPECT_EQ(reserve("res-riding", "{}", rosa_)->status, 409) << "a bike being ridden";

  auto made = reserve("res-cancel", R"({"expires_in_s": 600})", rosa_);
  ASSERT_EQ(made->status, 201) << made->body;
  const json r = json::parse(made->body);
  EXPECT_EQ(r["reserved_by"], "rosa");
  EXPECT_EQ(r["expires_at_us"].get<std::int64_t>() - r["started_at_us"].get<std::int64_t>(),
            600'000'000);
  EXPECT_EQ(reserve("res-cancel", "{}", rosa_)->status, 409) << "reserved twice";
  auto listed = stack_->client().Get("/api/reservations", {{"Cookie", vic.cookie}});
  ASSERT_EQ(listed->status, 200);
  ASSERT_EQ(json::parse(listed->body)["reservations"].size(), 1u) << listed->body;

  // GBFS: still listed, flagged; the other bikes are not.
  ASSERT_TRUE(gbfs_reserved_becomes(48.40, 11.40, true));
  EXPECT_EQ(gbfs_vehicle_at(48.41, 11.41)["is_reserved"], false);
  // MDS: reserved by reservation_start.
  json s = mds_status("res-cancel");
  EXPECT_EQ(s["last_event"]["vehicle_state"], "reserved") << s.dump();
  EXPECT_EQ(s["last_event"]["event_types"], json::array({"reservation_start"}));

  auto ended = cancel("res-cancel");
  ASSERT_EQ(ended->status, 200) << ended->body;
  EXPECT_EQ(json::parse(ended->body)["end_reason"], "cancelled");
  EXPECT_EQ(cancel("res-cancel")->status, 404) << "nothing left to cancel";
  ASSERT_TRUE(gbfs_reserved_becomes(48.40, 11.40, false));
  s = mds_status("res-cancel");
  EXPECT_EQ(s["last_event"]["vehicle_state"], "available") << s.dump();
  EXPECT_EQ(s["last_event"]["event_types"], json::array({"reservation_cancel"}));
  EXPECT_EQ(
      recent_events("res-cancel", t0),
      (std::vector<std::string>{"reserved:reservation_start", "available:reservation_cancel"}));

  // Audited, refusals included.
  const auto audit = stack_->rows(
      "SELECT action, result FROM console_audit WHERE action LIKE 'vehicle_reserv%' AND target IN "
      "('res-cancel', '/api/vehicles/res-cancel/reservation') ORDER BY id");
  std::vector<std::string> got;
  for (const auto& row : audit) got.push_back(row[0] + ":" + row[1]);
  EXPECT_EQ(got,
            (std::vector<std::string>{"vehicle_reserve:forbidden", "vehicle_reserve:refused_csrf",
                                      "vehicle_reserve:bad_request", "vehicle_reserve:ok",
                                      "vehicle_reserve:conflict", "vehicle_reservation_cancel:ok",
                                      "vehicle_reservation_cancel:not_found"}));
}

TEST_F(Reservations, ATripTakesTheReservedBikeAndAnExpiredOneFreesIt) {
  const std::int64_t t0 = now_us() - 1000;
  ASSERT_EQ(reserve("res-trip", "{}", rosa_)->status, 201);
  ASSERT_TRUE(gbfs_reserved_becomes(48.41, 11.41, true));
  // The rider who held it rides it: a ride record starting after the reservation.
  const std::int64_t start = now_us() + 1000;
  insert_ride(*stack_, {.vehicle = "res-trip",
                        .ride_id = "res-ride",
                        .sequence = 40,
                        .start_us = start,
                        .end_us = start + 2000,
                        .start_lat = 48.41,
                        .start_lon = 11.41,
                        .end_lat = 48.41,
                        .end_lon = 11.41});
  ASSERT_TRUE(wait_until([&] { return now_us() > start + 3000; }, 5s));
  // The trip consumed it: not reserved after the ride, though it has not expired.
  ASSERT_TRUE(gbfs_reserved_becomes(48.41, 11.41, false));
  EXPECT_EQ(recent_events("res-trip", t0),
            (std::vector<std::string>{"reserved:reservation_start", "on_trip:trip_start",
                                      "available:trip_end"}));
  EXPECT_EQ(cancel("res-trip")->status, 404);

  // A reservation past its expiry holds nothing (its end is its expiry: reservation_cancel).
  const fleetgw::PgParam p[] = {std::to_string(now_us() - 120'000'000),
                                std::to_string(now_us() - 60'000'000)};
  stack_->db().query(
      "INSERT INTO vehicle_reservations (vehicle_id, reserved_by, started_at_us, expires_at_us) "
      "VALUES ('res-expire', 'rosa', $1, $2)",
      p, "expired reservation");
  EXPECT_EQ(gbfs_vehicle_at(48.43, 11.43)["is_reserved"], false);
  EXPECT_EQ(
      recent_events("res-expire", now_us() - 180'000'000),
      (std::vector<std::string>{"reserved:reservation_start", "available:reservation_cancel"}));
  EXPECT_EQ(mds_status("res-expire")["last_event"]["vehicle_state"], "available");
}

}  // namespace
}  // namespace fleetgw::testing
