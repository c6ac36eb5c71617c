// The MDS 2.0 Provider API of `fleetgw serve` (issue 27) against PostgreSQL: authentication,
// version negotiation, paging, every response's required fields (written from MDS 2.0's
// data-types.md and the mds-openapi micromobility models: mds_spec_check.h), per-sample heading
// and accuracy in /mds/telemetry (the ingest's migration 8), and the state machine walked through
// a ride that leaves the operating area, a theft alarm, a low battery and a lost connection
// (status_history, the ingest's migration 4).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <set>

#include "tests/web/mds_spec_check.h"
#include "tests/web/registry_test_util.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;

constexpr std::int64_t kMin = 60'000'000;
constexpr const char* kHostileId = "mds-\"<script>alert(1)</script>";

// The MDS 2.0 OpenAPI definitions' checks (mds_spec_check.h).
void expect_event(const json& e) {
  const mds_spec::Problems p = mds_spec::check_event(e);
  EXPECT_TRUE(p.empty()) << e.dump() << mds_spec::join(p);
}
void expect_telemetry(const json& t) {
  const mds_spec::Problems p = mds_spec::check_telemetry(t);
  EXPECT_TRUE(p.empty()) << t.dump() << mds_spec::join(p);
}

class MdsApi : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ = std::make_unique<ServeStack>(
        std::vector<std::string>{"--provider-id", kTestProviderId, "--mds-page-size", "2"});
    register_ebike_type(*stack_);
    for (const char* id : {"mds-walk", "mds-riding", kHostileId}) register_vehicle(*stack_, id);
    std::string out;
    ASSERT_EQ(serve_admin(*stack_, {"--add-mds-agency", "test-city"}, &out), 0) << out;
    while (!out.empty() && out.back() == '\n') out.pop_back();
    token_ = out.substr(out.rfind('\n') + 1);

    hour_ = last_full_hour_us();
    t0_ = hour_ + 5 * kMin;
    stack_->insert_vehicle({.id = "mds-walk", .lat = 48.16, .lon = 11.56});
    stack_->insert_vehicle(
        {.id = "mds-riding", .lat = 48.17, .lon = 11.57, .mode = "VEHICLE_MODE_RIDING"});
    stack_->insert_vehicle({.id = kHostileId, .lat = 48.18, .lon = 11.58});
    // The riding bike's latest fix: heading 123.4 degrees, 4.5 m horizontal error (migration 4).
    stack_->db().exec(
        "UPDATE vehicle_state SET heading_ddeg = 1234, horizontal_error_dm = 45 WHERE "
        "vehicle_id = 'mds-riding'",
        "fix quality");
    // A ride that leaves the operating area and comes back, its track in telemetry.
    insert_ride(*stack_, {.vehicle = "mds-walk",
                          .ride_id = "walk-ride",
                          .sequence = 100,
                          .start_us = t0_,
                          .end_us = t0_ + 10 * kMin,
                          .start_lat = 48.15,
                          .start_lon = 11.55,
                          .end_lat = 48.16,
                          .end_lon = 11.56});
    for (int i = 1; i < 10; ++i) {
      insert_soc_sample(*stack_, "mds-walk", i, t0_ + i * kMin, 90 - i, 48.15 + i * 0.001, 11.55);
    }
    // One sample's fix carries heading and accuracy, as the ingest stores them (migration 8).
    stack_->db().exec(
        "UPDATE telemetry_samples SET heading_ddeg = 2715, horizontal_error_dm = 32 WHERE "
        "vehicle_id = 'mds-walk' AND sequence = 5",
        "sample fix quality");
    stack_->insert_alarm("mds-walk", 101, "ALARM_KIND_OUTSIDE_OPERATING_AREA",
                         "ALARM_TRANSITION_RAISED", t0_ + 4 * kMin);
    stack_->insert_alarm("mds-walk", 102, "ALARM_KIND_OUTSIDE_OPERATING_AREA",
                         "ALARM_TRANSITION_CLEARED", t0_ + 6 * kMin);
    // Parked: a theft alarm raised and cleared, a flat battery charged, then lost contact.
    stack_->insert_alarm("mds-walk", 103, "ALARM_KIND_UNAUTHORISED_MOVEMENT",
                         "ALARM_TRANSITION_RAISED", t0_ + 15 * kMin);
    stack_->insert_alarm("mds-walk", 104, "ALARM_KIND_UNAUTHORISED_MOVEMENT",
                         "ALARM_TRANSITION_CLEARED", t0_ + 20 * kMin);
    insert_soc_sample(*stack_, "mds-walk", 20, t0_ + 25 * kMin, 15, 48.16, 11.56);
    insert_soc_sample(*stack_, "mds-walk", 21, t0_ + 30 * kMin, 35, 48.16, 11.56);
    // Connection changes as the ingest records them (status_history): the broker's last will
    // at t0 + 40 min, back online at t0 + 50 min; the hostile-named bike lost 5 minutes ago.
    history("mds-walk", hour_ - 10 * kMin, "ONLINE_STATE_ONLINE", false);
    history("mds-walk", t0_ + 40 * kMin, "ONLINE_STATE_OFFLINE", true);
    history("mds-walk", t0_ + 50 * kMin, "ONLINE_STATE_ONLINE", false);
    history(kHostileId, now_us() - 5 * kMin, "ONLINE_STATE_OFFLINE", true);
  }
  static void TearDownTestSuite() { stack_.reset(); }

  static void history(const std::string& vehicle, std::int64_t at_us, const char* online,
                      bool last_will) {
    const fleetgw::PgParam p[] = {vehicle, std::to_string(at_us), online, last_will ? "t" : "f"};
    stack_->db().query(
        "INSERT INTO status_history (vehicle_id, created_at_us, online, last_will, connection, "
        "received_at_us) VALUES ($1, $2, $3, $4::boolean, 'CONNECTION_STATE_CONNECTED', $2)",
        p, "status_history row");
  }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  // Every item of `key` across the pages (links.next), each page checked for the envelope.
  static json collect(std::string path, const std::string& key) {
    json all = json::array();
    for (int page = 0; page < 50; ++page) {
      auto res = mds_get(*stack_, path, token_);
      EXPECT_TRUE(res);
      if (!res) break;
      EXPECT_EQ(res->status, 200) << path << ": " << res->body;
      EXPECT_EQ(res->get_header_value("Content-Type"), "application/vnd.mds+json;version=2.0");
      const json doc = json::parse(res->body);
      EXPECT_EQ(doc.value("version", ""), "2.0.0");
      const bool realtime = key == "vehicles" || key == "vehicles_status";
      const mds_spec::Problems p = mds_spec::check_payload(
          doc, key, realtime, [](const json&, const std::string&) { return mds_spec::Problems{}; });
      EXPECT_TRUE(p.empty()) << path << mds_spec::join(p);
      for (const json& item : doc[key]) all.push_back(item);
      EXPECT_TRUE(doc.contains("links") && doc["links"].contains("next"));
      if (doc["links"]["next"].is_null()) return all;
      const std::string next = doc["links"]["next"];
      EXPECT_EQ(next.rfind(stack_->url(), 0), 0u) << next;
      path = next.substr(stack_->url().size());
    }
    ADD_FAILURE() << "more than 50 pages";
    return all;
  }

  static std::vector<std::string> walk(const json& events) {
    std::vector<std::string> out;
    for (const json& e : events) {
      if (e["device_id"] != device("mds-walk")) continue;
      std::string types;
      for (const json& t : e["event_types"])
        types += (types.empty() ? "" : "+") + t.get<std::string>();
      out.push_back(e["vehicle_state"].get<std::string>() + ":" + types);
    }
    return out;
  }

  static std::string device(const std::string& vehicle) {
    return stack_->rows("SELECT device_id::text FROM registry_vehicles WHERE vehicle_id = $1",
                        {vehicle})[0][0];
  }

  static std::unique_ptr<ServeStack> stack_;
  static std::string token_;
  static std::int64_t hour_;
  static std::int64_t t0_;
};
std::unique_ptr<ServeStack> MdsApi::stack_;
std::string MdsApi::token_;
std::int64_t MdsApi::hour_ = 0;
std::int64_t MdsApi::t0_ = 0;

TEST_F(MdsApi, RefusedWithoutOrWithAWrongTokenAndForAnotherVersion) {
  auto res = mds_get(*stack_, "/mds/vehicles", "");
  EXPECT_EQ(res->status, 401);
  EXPECT_EQ(res->get_header_value("WWW-Authenticate").rfind("Bearer", 0), 0u);
  EXPECT_EQ(mds_get(*stack_, "/mds/vehicles", token_ + "x")->status, 401);
  EXPECT_EQ(mds_get(*stack_, "/mds/vehicles", "not-a-token")->status, 401);
  EXPECT_EQ(
      mds_get(*stack_, "/mds/vehicles", token_, "application/vnd.mds+json;version=1.2")->status,
      406);
  EXPECT_EQ(mds_get(*stack_, "/mds/vehicles", token_, "text/html")->status, 406);
  EXPECT_EQ(mds_get(*stack_, "/mds/vehicles", token_, "")->status, 200);
  EXPECT_EQ(mds_get(*stack_, "/mds/vehicles", token_, "application/vnd.mds+json")->status, 200);
}

TEST_F(MdsApi, HourParametersAreCheckedAndAnHourNotEndedIs404) {
  EXPECT_EQ(mds_get(*stack_, "/mds/trips", token_)->status, 400);
  EXPECT_EQ(mds_get(*stack_, "/mds/trips?end_time=2026-13-01T07", token_)->status, 400);
  EXPECT_EQ(mds_get(*stack_, "/mds/trips?end_time=yesterday", token_)->status, 400);
  EXPECT_EQ(
      mds_get(*stack_, "/mds/trips?end_time=" + hour_param(hour_ + 3'600'000'000), token_)->status,
      404);
  EXPECT_EQ(mds_get(*stack_, "/mds/events/recent?start_time=5&end_time=4", token_)->status, 400);
}

TEST_F(MdsApi, VehiclesCarryTheRegistryAndHostileIdsAsEscapedData) {
  const json vehicles = collect("/mds/vehicles", "vehicles");
  ASSERT_EQ(vehicles.size(), 3u);  // three pages of 2, 1 (--mds-page-size 2)
  bool hostile = false;
  for (const json& v : vehicles) {
    const mds_spec::Problems p = mds_spec::check_vehicle(v);
    EXPECT_TRUE(p.empty()) << v.dump() << mds_spec::join(p);
    EXPECT_EQ(v["provider_id"], kTestProviderId);
    ASSERT_TRUE(v["vehicle_id"].is_string());
    EXPECT_EQ(v["vehicle_type"], "bicycle");
    EXPECT_EQ(v["propulsion_types"], json::array({"human", "electric_assist"}));
    EXPECT_EQ(v["maximum_speed"], 25);
    EXPECT_EQ(v["battery_capacity"], 13800);
    hostile = hostile || v["vehicle_id"] == kHostileId;
  }
  EXPECT_TRUE(hostile);
  auto one = mds_get(*stack_, "/mds/vehicles/" + device(kHostileId), token_);
  ASSERT_EQ(one->status, 200);
  EXPECT_NE(one->body.find(R"(mds-\"<script>)"), std::string::npos) << one->body;
  EXPECT_EQ(json::parse(one->body)["vehicles"][0]["vehicle_id"], kHostileId);
}

TEST_F(MdsApi, TripsAndTheirTelemetryForAnHour) {
  const json trips = collect("/mds/trips?end_time=" + hour_param(hour_), "trips");
  ASSERT_EQ(trips.size(), 1u);
  const json& t = trips[0];
  EXPECT_EQ(t["provider_id"], kTestProviderId);
  EXPECT_EQ(t["device_id"], device("mds-walk"));
  EXPECT_TRUE(is_uuid_text(t["trip_id"]));
  EXPECT_EQ(t["start_time"], t0_ / 1000);
  EXPECT_EQ(t["end_time"], (t0_ + 10 * kMin) / 1000);
  EXPECT_EQ(t["duration"], 600);
  EXPECT_EQ(t["distance"], 2400);
  const mds_spec::Problems tp = mds_spec::check_trip(t);
  EXPECT_TRUE(tp.empty()) << t.dump() << mds_spec::join(tp);
  EXPECT_DOUBLE_EQ(t["start_location"]["lat"].get<double>(), 48.15);

  // The route: the ride's telemetry names the trip.
  const json tel = collect("/mds/telemetry?telemetry_time=" + hour_param(hour_), "telemetry");
  int on_trip = 0;
  int with_fix_quality = 0;
  for (const json& s : tel) {
    expect_telemetry(s);
    if (s["trip_ids"].is_array() && s["trip_ids"][0] == t["trip_id"]) ++on_trip;
    // Sample 5's own fix (set up with heading 271.5 degrees and 3.2 m accuracy).
    if (s["location"].contains("heading")) {
      ++with_fix_quality;
      EXPECT_DOUBLE_EQ(s["location"]["heading"].get<double>(), 271.5) << s.dump();
      EXPECT_DOUBLE_EQ(s["location"].value("horizontal_accuracy", 0.0), 3.2) << s.dump();
      EXPECT_EQ(s["timestamp"], (t0_ + 5 * kMin) / 1000);
    }
  }
  EXPECT_EQ(with_fix_quality, 1) << "heading and accuracy per sample (ingest migration 8)";
  EXPECT_EQ(on_trip, 9);
  EXPECT_EQ(tel.size(), 11u);  // + the two parked SOC samples, outside the trip
}

TEST_F(MdsApi, StateMachineThroughARideATheftAFlatBatteryAndALostConnection) {
  const json events = collect("/mds/events/historical?event_time=" + hour_param(hour_), "events");
  for (const json& e : events) expect_event(e);
  EXPECT_EQ(walk(events),
            (std::vector<std::string>{"on_trip:trip_start", "elsewhere:trip_leave_jurisdiction",
                                      "on_trip:trip_enter_jurisdiction", "available:trip_end",
                                      "non_operational:unspecified", "available:unspecified",
                                      "non_operational:battery_low", "available:battery_charged",
                                      "non_contactable:comms_lost", "available:comms_restored"}));
  // The trip events name the trip of /mds/trips.
  const json trips = collect("/mds/trips?end_time=" + hour_param(hour_), "trips");
  ASSERT_EQ(trips.size(), 1u);
  for (const json& e : events) {
    if (e["event_types"][0].get<std::string>().starts_with("trip_")) {
      EXPECT_EQ(e["trip_ids"], json::array({trips[0]["trip_id"]}));
    }
  }
  // The same events through events/recent, and ids stable across requests.
  const json recent = collect("/mds/events/recent?start_time=" + std::to_string(hour_ / 1000) +
                                  "&end_time=" + std::to_string((hour_ + 3'600'000'000) / 1000),
                              "events");
  EXPECT_EQ(walk(recent), walk(events));
  ASSERT_FALSE(recent.empty());
  EXPECT_EQ(recent[0]["event_id"], events[0]["event_id"]);
}

TEST_F(MdsApi, VehicleStatusShowsTheRideInProgressAndTheLostConnection) {
  const json status = collect("/mds/vehicles/status", "vehicles_status");
  ASSERT_EQ(status.size(), 3u);
  for (const json& s : status) {
    EXPECT_TRUE(is_uuid_text(s["device_id"]));
    EXPECT_EQ(s["provider_id"], kTestProviderId);
    expect_event(s["last_event"]);
    expect_telemetry(s["last_telemetry"]);
    if (s["device_id"] == device("mds-riding")) {
      EXPECT_EQ(s["last_event"]["vehicle_state"], "on_trip");
      EXPECT_EQ(s["last_event"]["event_types"], json::array({"trip_start"}));
      EXPECT_DOUBLE_EQ(s["last_telemetry"]["location"].value("heading", 0.0), 123.4);
      EXPECT_DOUBLE_EQ(s["last_telemetry"]["location"].value("horizontal_accuracy", 0.0), 4.5);
    }
    if (s["device_id"] == device("mds-walk")) {
      EXPECT_EQ(s["last_event"]["vehicle_state"], "available");
    }
    if (s["device_id"] == device(kHostileId)) {
      EXPECT_EQ(s["last_event"]["vehicle_state"], "non_contactable");
      EXPECT_EQ(s["last_event"]["event_types"], json::array({"comms_lost"}));
    }
  }
  auto one = mds_get(*stack_, "/mds/vehicles/status/" + device("mds-riding"), token_);
  ASSERT_EQ(one->status, 200);
  EXPECT_EQ(json::parse(one->body)["vehicles_status"].size(), 1u);
}

}  // namespace
}  // namespace fleetgw::testing
