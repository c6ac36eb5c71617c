// GBFS v3.0 feeds of `fleetgw serve` (issue 27) against PostgreSQL: every file checked against
// the v3.0 specification's required fields, types and rules (gbfs_spec_check.h, written from
// gbfs.md v3.0), vehicle id rotation across a trip, no vehicle in a ride, ETag/If-None-Match,
// the zone bundle in force as geofencing_zones, and its rings written by the right-hand rule
// (a left-hand ring reversed, a right-hand document unchanged).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <variant>

#include "backend/web/gbfs_feeds.h"
#include "fleetgw/v1/zones.pb.h"
#include "proto/convert/gbfs_zones.h"
#include "tests/support/wait.h"
#include "tests/web/gbfs_spec_check.h"
#include "tests/web/registry_test_util.h"

namespace fleetgw::testing {
namespace {

using nlohmann::json;
namespace pb = fleetgw::v1;

namespace spec = gbfs_spec;

// A document's problems, for EXPECT_TRUE(p.empty()) << ...
std::string gbfs_problems_text(const spec::Problems& p) {
  return "GBFS v3.0 problems:" + spec::join(p);
}

pb::ZoneRing ring(std::initializer_list<std::pair<double, double>> lat_lon) {
  pb::ZoneRing r;
  for (const auto& [lat, lon] : lat_lon) {
    r.add_lat_e7(static_cast<int>(lat * 1e7));
    r.add_lon_e7(static_cast<int>(lon * 1e7));
  }
  return r;
}

// A city's GBFS-shaped bundle (as `fleetgw zones sign` makes it from a GBFS file that follows
// the right-hand rule): a windowed no-ride MultiPolygon (two squares, one with a hole), a slow
// zone for one vehicle type only, and global rules.
pb::ZoneBundle city_bundle() {
  pb::ZoneBundle b;
  b.set_version(7);
  b.set_issued_at_us(1'760'000'000'000'000);
  b.set_precedence(pb::ZONE_PRECEDENCE_FIRST_MATCH);
  pb::Zone* market = b.add_zones();
  market->set_id("market");
  market->set_name("Market square");
  market->set_kind(pb::ZONE_KIND_RULES);
  *market->add_rings() = ring({{48.0, 11.0}, {48.0, 11.1}, {48.1, 11.1}, {48.1, 11.0}});
  *market->add_rings() = ring({{48.02, 11.02}, {48.08, 11.02}, {48.08, 11.08}, {48.02, 11.08}});
  *market->add_rings() = ring({{48.2, 11.2}, {48.2, 11.3}, {48.3, 11.3}, {48.3, 11.2}});
  market->add_polygon_rings(2);
  market->add_polygon_rings(1);
  market->set_start_us(1'767'225'600'000'000);  // 2026-01-01T00:00:00Z
  market->set_end_us(1'767'254'400'000'000);    // 2026-01-01T08:00:00Z
  pb::LocalizedText* de = market->add_names();
  de->set_text("Marktplatz <b>\"alt\"</b>");
  de->set_language("de");
  pb::ZoneRule* no_ride = market->add_rules();
  no_ride->set_ride_start_allowed(false);
  no_ride->set_ride_end_allowed(false);
  no_ride->set_ride_through_allowed(false);
  pb::Zone* river = b.add_zones();
  river->set_id("river");
  river->set_kind(pb::ZONE_KIND_RULES);
  *river->add_rings() = ring({{48.4, 11.4}, {48.4, 11.5}, {48.5, 11.5}, {48.5, 11.4}});
  pb::ZoneRule* slow = river->add_rules();
  slow->add_vehicle_type_ids("ebike");
  slow->set_ride_start_allowed(true);
  slow->set_ride_end_allowed(true);
  slow->set_ride_through_allowed(true);
  slow->set_maximum_speed_kph(10);
  pb::ZoneRule* global = b.add_default_rules();
  global->set_ride_start_allowed(true);
  global->set_ride_end_allowed(true);
  global->set_ride_through_allowed(true);
  return b;
}

class GbfsFeeds : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (postgres_bin_dir().empty()) return;
    stack_ =
        std::make_unique<ServeStack>(std::vector<std::string>{"--provider-id", kTestProviderId});
    register_ebike_type(*stack_);
    for (const char* id : {"gbfs-parked", "gbfs-low", "gbfs-alarm", "gbfs-offline", "gbfs-riding",
                           "gbfs-rotate", "gbfs-missed", "<script>\"bike\"</script>"}) {
      register_vehicle(*stack_, id);
    }
    stack_->insert_vehicle({.id = "gbfs-parked", .lat = 48.20, .lon = 11.60});
    stack_->insert_vehicle({.id = "gbfs-low", .lat = 48.21, .lon = 11.61, .soc_pct = 12});
    stack_->insert_vehicle({.id = "gbfs-alarm", .lat = 48.22, .lon = 11.62});
    stack_->insert_alarm("gbfs-alarm", 1, "ALARM_KIND_UNAUTHORISED_MOVEMENT",
                         "ALARM_TRANSITION_RAISED", now_us());
    stack_->insert_vehicle(
        {.id = "gbfs-offline", .lat = 48.23, .lon = 11.63, .status_online = false});
    stack_->insert_vehicle(
        {.id = "gbfs-riding", .lat = 48.24, .lon = 11.64, .mode = "VEHICLE_MODE_RIDING"});
    stack_->insert_vehicle({.id = "gbfs-rotate", .lat = 48.30, .lon = 11.70});
    stack_->insert_vehicle({.id = "gbfs-missed", .lat = 48.31, .lon = 11.71});
    stack_->insert_vehicle({.id = "<script>\"bike\"</script>", .lat = 48.32, .lon = 11.72});
    stack_->insert_vehicle({.id = "gbfs-unregistered", .lat = 48.33, .lon = 11.73});
    // gbfs-parked measured 15 Wh/km on its rides: 80 % of 500 Wh -> 26,667 m.
    const std::int64_t t = now_us() - 3'600'000'000;
    insert_ride(*stack_, {.vehicle = "gbfs-parked",
                          .ride_id = "p1",
                          .sequence = 5,
                          .start_us = t,
                          .end_us = t + 600'000'000,
                          .distance_m = 2400,
                          .energy_mwh = 36000});
    const std::string bundle_file = (stack_->dir() / "city.zones").string();
    pb::SignedZoneBundle signed_msg;
    signed_msg.set_bundle(city_bundle().SerializeAsString());
    signed_msg.set_signature(std::string(64, 's'));
    signed_msg.set_key_id("ops");
    std::ofstream(bundle_file, std::ios::binary) << signed_msg.SerializeAsString();
    std::string out;
    ASSERT_EQ(serve_admin(*stack_, {"--import-zone-bundle", bundle_file}, &out), 0) << out;
  }
  static void TearDownTestSuite() { stack_.reset(); }
  void SetUp() override {
    if (!stack_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  }

  static json feed(const std::string& name) {
    auto res = stack_->client().Get("/gbfs/" + name + ".json");
    EXPECT_TRUE(res) << name;
    if (!res) return nullptr;
    EXPECT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
    EXPECT_EQ(res->get_header_value("Access-Control-Allow-Origin"), "*");
    EXPECT_FALSE(res->get_header_value("ETag").empty());
    json doc = json::parse(res->body);
    const spec::Problems p = spec::check_envelope(doc);
    EXPECT_TRUE(p.empty()) << name << ": " << gbfs_problems_text(p);
    return doc;
  }

  // The listed vehicle at (lat, lon), or null.
  static json vehicle_at(const json& status, double lat, double lon) {
    for (const json& v : status["data"]["vehicles"]) {
      if (std::abs(v["lat"].get<double>() - lat) < 1e-6 &&
          std::abs(v["lon"].get<double>() - lon) < 1e-6)
        return v;
    }
    return nullptr;
  }

  static std::unique_ptr<ServeStack> stack_;
};
std::unique_ptr<ServeStack> GbfsFeeds::stack_;

TEST_F(GbfsFeeds, DiscoveryListsEveryFeedAndEachIsServed) {
  const json doc = feed("gbfs");
  const spec::Problems p = spec::check_discovery(doc);
  ASSERT_TRUE(p.empty()) << gbfs_problems_text(p);
  std::set<std::string> names;
  for (const json& f : doc["data"]["feeds"]) {
    ASSERT_TRUE(f["name"].is_string() && f["url"].is_string());
    names.insert(f["name"]);
    const std::string url = f["url"];
    ASSERT_EQ(url.rfind(stack_->url() + "/gbfs/", 0), 0u) << url;
    feed(url.substr(stack_->url().size() + 6, url.size() - stack_->url().size() - 11));
  }
  EXPECT_EQ(names, (std::set<std::string>{"gbfs", "system_information", "vehicle_types",
                                          "vehicle_status", "geofencing_zones"}));
}

TEST_F(GbfsFeeds, SystemInformationHasEveryRequiredField) {
  const spec::Problems p = spec::check_system_information(feed("system_information"));
  EXPECT_TRUE(p.empty()) << gbfs_problems_text(p);
}

TEST_F(GbfsFeeds, VehicleTypesFollowTheSpecification) {
  const json doc = feed("vehicle_types");
  const spec::Problems p = spec::check_vehicle_types(doc);
  ASSERT_TRUE(p.empty()) << gbfs_problems_text(p);
  bool ebike = false;
  for (const json& t : doc["data"]["vehicle_types"]) {
    if (t["vehicle_type_id"] == "ebike") {
      ebike = true;
      EXPECT_EQ(t["max_range_meters"].get<double>(), 50000);  // 500 Wh / 10 Wh/km
      EXPECT_EQ(t["max_permitted_speed"], 25);
    }
  }
  EXPECT_TRUE(ebike);
}

TEST_F(GbfsFeeds, VehicleStatusFollowsTheSpecificationAndHidesRidesAndOwnIds) {
  auto res = stack_->client().Get("/gbfs/vehicle_status.json");
  ASSERT_EQ(res->status, 200);
  // Not one vehicle's own id leaves the server, hostile or not.
  for (const char* id : {"gbfs-parked", "gbfs-low", "script", "gbfs-unregistered"}) {
    EXPECT_EQ(res->body.find(id), std::string::npos) << id;
  }
  const json doc = json::parse(res->body);
  spec::TypeTable types;
  const spec::Problems tp = spec::check_vehicle_types(feed("vehicle_types"), &types);
  ASSERT_TRUE(tp.empty()) << gbfs_problems_text(tp);
  const spec::Problems p = spec::check_vehicle_status(doc, types);
  EXPECT_TRUE(p.empty()) << gbfs_problems_text(p);
  for (const json& v : doc["data"]["vehicles"]) {
    EXPECT_TRUE(v.contains("last_reported")) << v.dump();
    EXPECT_TRUE(v.contains("current_fuel_percent")) << v.dump();
  }
  EXPECT_TRUE(vehicle_at(doc, 48.24, 11.64).is_null()) << "a vehicle in a ride is listed";
  EXPECT_TRUE(vehicle_at(doc, 48.33, 11.73).is_null()) << "an unregistered vehicle is listed";
  ASSERT_FALSE(vehicle_at(doc, 48.32, 11.72).is_null());
  const json parked = vehicle_at(doc, 48.20, 11.60);
  ASSERT_FALSE(parked.is_null());
  EXPECT_FALSE(parked["is_disabled"].get<bool>());
  EXPECT_EQ(parked["current_range_meters"].get<double>(), 26667);  // measured 15 Wh/km
  EXPECT_DOUBLE_EQ(parked["current_fuel_percent"].get<double>(), 0.8);
  EXPECT_EQ(vehicle_at(doc, 48.32, 11.72)["current_range_meters"].get<double>(), 20000);  // range_m
  EXPECT_TRUE(vehicle_at(doc, 48.21, 11.61)["is_disabled"].get<bool>()) << "low battery";
  EXPECT_TRUE(vehicle_at(doc, 48.22, 11.62)["is_disabled"].get<bool>()) << "theft alarm";
  EXPECT_TRUE(vehicle_at(doc, 48.23, 11.63)["is_disabled"].get<bool>()) << "offline";
}

TEST_F(GbfsFeeds, VehicleIdRotatesAfterATripAndIsStableBetweenTrips) {
  json before;
  ASSERT_TRUE(wait_until(
      [&] {
        before = vehicle_at(feed("vehicle_status"), 48.30, 11.70);
        return !before.is_null();
      },
      std::chrono::seconds(10)));
  const std::string id1 = before["vehicle_id"];
  stack_->db().exec(
      "UPDATE vehicle_state SET mode = 'VEHICLE_MODE_RIDING' WHERE vehicle_id = 'gbfs-rotate'",
      "ride starts");
  ASSERT_TRUE(
      wait_until([&] { return feed("vehicle_status").dump().find(id1) == std::string::npos; },
                 std::chrono::seconds(10)))
      << "the riding vehicle stays listed";
  const std::int64_t t = now_us();
  insert_ride(*stack_, {.vehicle = "gbfs-rotate",
                        .ride_id = "r1",
                        .sequence = 9,
                        .start_us = t - 300'000'000,
                        .end_us = t});
  stack_->db().exec(
      "UPDATE vehicle_state SET mode = 'VEHICLE_MODE_PARKED', lat_e7 = 483050000, lon_e7 = "
      "117050000 WHERE vehicle_id = 'gbfs-rotate'",
      "ride ends");
  json after;
  ASSERT_TRUE(wait_until(
      [&] {
        after = vehicle_at(feed("vehicle_status"), 48.305, 11.705);
        return !after.is_null();
      },
      std::chrono::seconds(10)));
  const std::string id2 = after["vehicle_id"];
  EXPECT_NE(id2, id1);
  // Stable between trips: a later build (a new last_updated) keeps it.
  const std::string built = feed("vehicle_status")["last_updated"];
  json later;
  ASSERT_TRUE(wait_until(
      [&] {
        later = feed("vehicle_status");
        return later["last_updated"] != built;
      },
      std::chrono::seconds(10)));
  EXPECT_EQ(vehicle_at(later, 48.305, 11.705)["vehicle_id"], id2);
  EXPECT_EQ(later.dump().find(id1), std::string::npos);
}

TEST_F(GbfsFeeds, ARideNoBuildSawStillRotatesTheIdWhenItsRecordArrives) {
  json before;
  ASSERT_TRUE(wait_until(
      [&] {
        before = vehicle_at(feed("vehicle_status"), 48.31, 11.71);
        return !before.is_null();
      },
      std::chrono::seconds(10)));
  const std::int64_t t = now_us() + 1'000'000;
  insert_ride(*stack_, {.vehicle = "gbfs-missed",
                        .ride_id = "m1",
                        .sequence = 3,
                        .start_us = t,
                        .end_us = t + 1000});
  ASSERT_TRUE(wait_until(
      [&] {
        const json v = vehicle_at(feed("vehicle_status"), 48.31, 11.71);
        return !v.is_null() && v["vehicle_id"] != before["vehicle_id"];
      },
      std::chrono::seconds(10)));
}

TEST_F(GbfsFeeds, EtagAnswers304AndAnotherTagTheFeed) {
  auto first = stack_->client().Get("/gbfs/vehicle_types.json");
  ASSERT_EQ(first->status, 200);
  const std::string etag = first->get_header_value("ETag");
  ASSERT_FALSE(etag.empty());
  auto again = stack_->client().Get("/gbfs/vehicle_types.json", {{"If-None-Match", etag}});
  EXPECT_EQ(again->status, 304);
  EXPECT_TRUE(again->body.empty());
  EXPECT_EQ(again->get_header_value("ETag"), etag);
  auto other = stack_->client().Get("/gbfs/vehicle_types.json", {{"If-None-Match", "W/\"other\""}});
  EXPECT_EQ(other->status, 200);
  EXPECT_FALSE(other->body.empty());
}

TEST_F(GbfsFeeds, GeofencingZonesAreTheBundleInForce) {
  const json doc = feed("geofencing_zones");
  spec::TypeTable types;
  spec::check_vehicle_types(feed("vehicle_types"), &types);
  const spec::Problems p = spec::check_geofencing_zones(doc, types);
  ASSERT_TRUE(p.empty()) << gbfs_problems_text(p);
  const json& d = doc["data"];
  ASSERT_EQ(d["global_rules"].size(), 1u);
  const json& features = d["geofencing_zones"]["features"];
  ASSERT_EQ(features.size(), 2u);
  const json& market = features[0];  // GBFS precedence: bundle order kept
  EXPECT_EQ(market["geometry"]["coordinates"].size(), 2u);
  EXPECT_EQ(market["geometry"]["coordinates"][0].size(), 2u);  // outer + hole
  EXPECT_EQ(market["properties"]["start"], "2026-01-01T00:00:00Z");
  EXPECT_EQ(market["properties"]["end"], "2026-01-01T08:00:00Z");
  EXPECT_EQ(market["properties"]["name"][0]["text"], "Marktplatz <b>\"alt\"</b>");
  EXPECT_EQ(market["properties"]["name"][0]["language"], "de");
  EXPECT_FALSE(market["properties"]["rules"][0]["ride_through_allowed"].get<bool>());
  const json& river = features[1]["properties"]["rules"][0];
  EXPECT_EQ(river["maximum_speed_kph"], 10);
  EXPECT_EQ(river["vehicle_type_ids"], json::array({"ebike"}));
}

TEST(GbfsZones, AnOlderUnionBundleListsTheMostRestrictiveZonesFirst) {
  pb::ZoneBundle b;
  b.set_version(1);
  const auto add = [&](const char* id, pb::ZoneKind k, unsigned kph) {
    pb::Zone* z = b.add_zones();
    z->set_id(id);
    z->set_kind(k);
    z->set_speed_limit_kmh(kph);
    *z->add_rings() = ring({{48.0, 11.0}, {48.0, 11.1}, {48.1, 11.1}, {48.1, 11.0}});
  };
  add("area", pb::ZONE_KIND_OPERATING_AREA, 0);
  add("slow15", pb::ZONE_KIND_SLOW, 15);
  add("parking", pb::ZONE_KIND_NO_PARKING, 0);
  add("slow6", pb::ZONE_KIND_SLOW, 6);
  add("noride", pb::ZONE_KIND_NO_RIDE, 0);
  const json d = fleetgw::web::gbfs_zones_from_bundle(b.SerializeAsString(), {});
  const spec::Problems p = spec::check_geofencing_zones(
      {{"last_updated", "2026-11-29T08:00:00Z"}, {"ttl", 60}, {"version", "3.0"}, {"data", d}}, {});
  EXPECT_TRUE(p.empty()) << gbfs_problems_text(p);
  std::vector<json> firsts;
  for (const json& f : d["geofencing_zones"]["features"]) {
    firsts.push_back(f["properties"]["rules"][0]);
  }
  ASSERT_EQ(firsts.size(), 5u);
  EXPECT_FALSE(firsts[0]["ride_through_allowed"].get<bool>());  // no-ride
  EXPECT_EQ(firsts[1]["maximum_speed_kph"], 6);                 // lowest limit first
  EXPECT_EQ(firsts[2]["maximum_speed_kph"], 15);
  EXPECT_FALSE(firsts[3]["ride_end_allowed"].get<bool>());  // no-parking
  EXPECT_TRUE(firsts[4]["ride_end_allowed"].get<bool>());   // operating area
  ASSERT_EQ(d["global_rules"].size(), 1u);                  // outside it: no start, no end
  EXPECT_FALSE(d["global_rules"][0]["ride_end_allowed"].get<bool>());
}

// GBFS's right-hand rule on export (proto/convert/gbfs_zones.h): a bundle whose rings were
// signed clockwise (a city file drawn left-handed) is written with counter-clockwise exterior
// rings and clockwise holes from the same first vertex, the bike's area unchanged; a document
// that was right-hand already comes back exactly (`zones export` writes it back unchanged).
TEST(GbfsZones, RingsAreWrittenByTheRightHandRuleAndARightHandDocumentComesBackUnchanged) {
  pb::ZoneBundle b = city_bundle();
  const json right = fleetgw::convert::gbfs_from_zone_bundle(b, {.ttl_s = 60});
  const spec::Problems rp = spec::check_geofencing_zones(right, {});
  ASSERT_TRUE(rp.empty()) << gbfs_problems_text(rp);
  // Through the import and back: identical.
  const auto imported = fleetgw::convert::zone_bundle_from_gbfs(right.dump());
  ASSERT_TRUE(std::holds_alternative<fleetgw::convert::GbfsZonesImport>(imported));
  pb::ZoneBundle again = std::get<fleetgw::convert::GbfsZonesImport>(imported).bundle;
  again.set_version(b.version());
  again.set_issued_at_us(b.issued_at_us());
  EXPECT_EQ(fleetgw::convert::gbfs_from_zone_bundle(again, {.ttl_s = 60}), right);

  // Every ring reversed (exteriors clockwise, the hole counter-clockwise): left-handed.
  pb::ZoneBundle left = b;
  for (pb::Zone& z : *left.mutable_zones()) {
    for (pb::ZoneRing& r : *z.mutable_rings()) {
      std::reverse(r.mutable_lat_e7()->begin(), r.mutable_lat_e7()->end());
      std::reverse(r.mutable_lon_e7()->begin(), r.mutable_lon_e7()->end());
    }
  }
  const json fixed = fleetgw::convert::gbfs_from_zone_bundle(left, {.ttl_s = 60});
  const spec::Problems fp = spec::check_geofencing_zones(fixed, {});
  EXPECT_TRUE(fp.empty()) << gbfs_problems_text(fp);
  // The same vertices as the right-hand export, and each ring closed by its first.
  const json& a = right["data"]["geofencing_zones"]["features"];
  const json& c = fixed["data"]["geofencing_zones"]["features"];
  ASSERT_EQ(a.size(), c.size());
  for (std::size_t f = 0; f < a.size(); ++f) {
    const json& pa = a[f]["geometry"]["coordinates"];
    const json& pc = c[f]["geometry"]["coordinates"];
    ASSERT_EQ(pa.size(), pc.size());
    for (std::size_t i = 0; i < pa.size(); ++i) {
      for (std::size_t k = 0; k < pa[i].size(); ++k) {
        // As sets: the closing position repeats each ring's own first vertex.
        std::set<std::string> va, vc;
        for (const json& pos : pa[i][k]) va.insert(pos.dump());
        for (const json& pos : pc[i][k]) vc.insert(pos.dump());
        EXPECT_EQ(va, vc) << "feature " << f << " polygon " << i << " ring " << k;
      }
    }
  }
  // Ungrouped rings (an older bundle): the ring inside the other is the hole.
  pb::ZoneBundle ungrouped;
  ungrouped.set_version(1);
  pb::Zone* z = ungrouped.add_zones();
  z->set_id("donut");
  z->set_kind(pb::ZONE_KIND_NO_RIDE);
  *z->add_rings() = ring({{48.0, 11.0}, {48.1, 11.0}, {48.1, 11.1}, {48.0, 11.1}});  // clockwise
  *z->add_rings() = ring({{48.02, 11.02}, {48.02, 11.08}, {48.08, 11.08}, {48.08, 11.02}});
  const json donut = fleetgw::convert::gbfs_from_zone_bundle(ungrouped, {.ttl_s = 60});
  const spec::Problems dp = spec::check_geofencing_zones(donut, {});
  EXPECT_TRUE(dp.empty()) << gbfs_problems_text(dp);
}

// The checker itself fails on what the specification forbids (so a feed that breaks a rule
// cannot pass the tests above).
TEST(GbfsSpecCheck, RefusesWhatTheSpecificationForbids) {
  const json ok = {{"last_updated", "2026-11-29T08:00:00Z"},
                   {"ttl", 15},
                   {"version", "3.0"},
                   {"data",
                    {{"vehicles",
                      {{{"vehicle_id", "a"},
                        {"lat", 48.1},
                        {"lon", 11.5},
                        {"is_reserved", false},
                        {"is_disabled", false},
                        {"vehicle_type_id", "ebike"},
                        {"current_range_meters", 1000}}}}}}};
  const spec::TypeTable types = {{"ebike", "electric_assist"}};
  ASSERT_TRUE(spec::check_vehicle_status(ok, types).empty());
  const auto broken = [&](const std::function<void(json&)>& edit) {
    json d = ok;
    edit(d);
    return !spec::check_vehicle_status(d, types).empty();
  };
  EXPECT_TRUE(broken([](json& d) { d["version"] = "2.3"; }));
  EXPECT_TRUE(broken([](json& d) { d["last_updated"] = 1700000000; }));
  EXPECT_TRUE(broken([](json& d) { d["ttl"] = -1; }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0].erase("is_reserved"); }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0]["is_disabled"] = 0; }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0].erase("current_range_meters"); }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0]["vehicle_type_id"] = "car"; }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0]["current_fuel_percent"] = 80; }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"][0]["lat"] = 91; }));
  EXPECT_TRUE(broken([](json& d) { d["data"]["vehicles"].push_back(d["data"]["vehicles"][0]); }));
  json cw = {
      {"last_updated", "2026-11-29T08:00:00Z"},
      {"ttl", 0},
      {"version", "3.0"},
      {"data",
       {{"geofencing_zones",
         {{"type", "FeatureCollection"},
          {"features",
           {{{"type", "Feature"},
             {"properties", json::object()},
             {"geometry",
              {{"type", "MultiPolygon"},
               {"coordinates",
                {{{{11.0, 48.0}, {11.0, 48.1}, {11.1, 48.1}, {11.1, 48.0}, {11.0, 48.0}}}}}}}}}}}},
        {"global_rules", json::array()}}}};
  EXPECT_FALSE(spec::check_geofencing_zones(cw, {}).empty()) << "a clockwise exterior ring";
  cw["data"].erase("global_rules");
  EXPECT_FALSE(spec::check_geofencing_zones(cw, {}).empty());
}

}  // namespace
}  // namespace fleetgw::testing
