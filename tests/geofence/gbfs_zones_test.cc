// GBFS v3.0 geofencing_zones.json <-> ZoneBundle (issue 27, proto/convert/gbfs_zones.h): a city's
// file (tests/geofence/data/ljubljana_geofencing_zones.json: eight features with every rule
// kind, a MultiPolygon of two polygons with a hole, time windows, a vehicle-type rule,
// global_rules) becomes a bundle the gateway accepts and comes back as the same document; what
// the bike cannot enforce is refused naming the rule and its JSON path, never dropped.
#include "proto/convert/gbfs_zones.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "gateway/geofence/zone_bundle.h"

namespace fleetgw::convert {
namespace {

using nlohmann::json;

std::string city_text() {
  std::ifstream in(std::string(FLEETGW_SOURCE_DIR) +
                   "/tests/geofence/data/ljubljana_geofencing_zones.json");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A minimal v3.0 document around one feature's properties (and optional more members).
std::string one_feature(const std::string& properties, const std::string& data_extra = "") {
  return R"({"last_updated":"2026-11-29T08:00:00Z","ttl":0,"version":"3.0","data":{
    "geofencing_zones":{"type":"FeatureCollection","features":[
      {"type":"Feature","geometry":{"type":"MultiPolygon","coordinates":[[[[14.5,46.0],
       [14.51,46.0],[14.51,46.01],[14.5,46.01],[14.5,46.0]]]]},"properties":)" +
         properties + R"(}]},"global_rules":[])" + data_extra + "}}";
}

std::string refusal(const std::string& text) {
  auto r = zone_bundle_from_gbfs(text);
  if (auto* e = std::get_if<std::string>(&r)) return *e;
  return "(accepted)";
}

TEST(GbfsZones, TheCityFileBecomesABundleTheGatewayAcceptsAndComesBackIdentical) {
  const std::string text = city_text();
  ASSERT_FALSE(text.empty());
  ASSERT_TRUE(is_gbfs_geofencing_zones(text));
  auto r = zone_bundle_from_gbfs(text);
  ASSERT_TRUE(std::holds_alternative<GbfsZonesImport>(r)) << std::get<std::string>(r);
  auto& imported = std::get<GbfsZonesImport>(r);
  EXPECT_TRUE(imported.notes.empty()) << ::testing::PrintToString(imported.notes);
  v1::ZoneBundle& b = imported.bundle;
  EXPECT_EQ(b.precedence(), v1::ZONE_PRECEDENCE_FIRST_MATCH);
  ASSERT_EQ(b.zones_size(), 8);
  for (const auto& z : b.zones()) EXPECT_EQ(z.kind(), v1::ZONE_KIND_RULES) << z.id();
  EXPECT_EQ(b.zones(0).id(), "gbfs-0");
  EXPECT_EQ(b.zones(0).name(), "Festival Ljubljana");
  ASSERT_EQ(b.zones(0).names_size(), 2);
  EXPECT_EQ(b.zones(0).names(1).language(), "en");
  EXPECT_EQ(b.zones(0).start_us(), *us_from_rfc3339("2024-06-01T00:00:00Z"));
  EXPECT_EQ(b.zones(0).end_us(), *us_from_rfc3339("2099-12-31T23:00:00Z"));
  // The old town: two polygons (the first with its courtyard hole), two rules in order.
  const v1::Zone& old_town = b.zones(3);
  EXPECT_EQ(old_town.rings_size(), 3);
  EXPECT_EQ(
      std::vector<std::uint32_t>(old_town.polygon_rings().begin(), old_town.polygon_rings().end()),
      (std::vector<std::uint32_t>{2, 1}));
  ASSERT_EQ(old_town.rules_size(), 2);
  EXPECT_EQ(old_town.rules(0).vehicle_type_ids(0), "cargo-ebike");
  EXPECT_EQ(old_town.rules(0).maximum_speed_kph(), 6u);
  EXPECT_TRUE(old_town.rules(1).vehicle_type_ids().empty());
  EXPECT_EQ(old_town.rules(1).maximum_speed_kph(), 12u);
  EXPECT_FALSE(b.zones(4).rules(0).ride_start_allowed());  // the station: no-start
  EXPECT_TRUE(b.zones(4).rules(0).ride_end_allowed());
  EXPECT_FALSE(b.zones(4).rules(0).has_maximum_speed_kph());
  ASSERT_EQ(b.default_rules_size(), 1);
  EXPECT_EQ(b.default_rules(0).maximum_speed_kph(), 15u);

  // What the gateway would do with it.
  b.set_version(1);
  b.set_issued_at_us(1'790'000'000'000'000);
  auto compiled = geofence::compile_zones(b);
  ASSERT_TRUE(std::holds_alternative<geofence::ZoneSet>(compiled))
      << std::get<std::string>(compiled);
  const auto& set = std::get<geofence::ZoneSet>(compiled);
  EXPECT_EQ(set.precedence, geofence::Precedence::kFirstMatch);
  EXPECT_EQ(set.zones[3].effects_for("cargo-ebike")->speed_limit_kmh, 6);
  EXPECT_EQ(set.zones[3].effects_for("city-ebike")->speed_limit_kmh, 12);

  // Back: the same document, member for member (last_updated and ttl as given).
  GbfsExportOptions options;
  options.last_updated_us = *us_from_rfc3339("2026-11-29T08:00:00Z");
  options.ttl_s = 60;
  const json back = gbfs_from_zone_bundle(b, options);
  EXPECT_EQ(back, json::parse(text)) << back.dump(1);
  // And again through the bytes a gateway keeps: nothing depends on the in-memory message.
  v1::ZoneBundle parsed;
  ASSERT_TRUE(parsed.ParseFromString(b.SerializeAsString()));
  EXPECT_EQ(gbfs_from_zone_bundle(parsed, options), back);
}

TEST(GbfsZones, WhatTheBikeCannotEnforceIsRefusedNamingTheRuleAndItsPlace) {
  const std::string rule = R"("ride_start_allowed":true,"ride_end_allowed":true,)"
                           R"("ride_through_allowed":true)";
  EXPECT_EQ(refusal(one_feature(R"({"rules":[{)" + rule + R"(},{)" + rule +
                                R"(,"station_parking":true}]})")),
            "data.geofencing_zones.features[0].properties.rules[1].station_parking: true is not "
            "enforced by the bike (it knows no stations); refusing rather than dropping the rule");
  EXPECT_EQ(refusal(one_feature(R"({"rules":[{)" + rule + R"(,"minimum_age":18}]})")),
            "data.geofencing_zones.features[0].properties.rules[0].minimum_age: unknown rule "
            "property 'minimum_age'; the bike cannot enforce a rule it does not know (refused, "
            "not dropped)");
  EXPECT_EQ(refusal(one_feature(R"({"rules":[{)" + rule + R"(,"maximum_speed_kph":12.5}]})")),
            "data.geofencing_zones.features[0].properties.rules[0].maximum_speed_kph: 12.5 is not "
            "a whole number of km/h in 0..255");
  EXPECT_EQ(refusal(one_feature(R"({"rules":[{"ride_start_allowed":true,)"
                                R"("ride_end_allowed":true}]})")),
            "data.geofencing_zones.features[0].properties.rules[0].ride_through_allowed: missing "
            "(required by GBFS v3.0)");
  EXPECT_EQ(
      refusal(one_feature(R"({"start":"2026-12-01T00:00:00Z","end":"2026-11-01T00:00:00Z"})")),
      "data.geofencing_zones.features[0].properties.end: not after start");
  EXPECT_EQ(refusal(one_feature(R"({"start":"tomorrow"})")),
            "data.geofencing_zones.features[0].properties.start: \"tomorrow\" is not an RFC 3339 "
            "date-time");
  EXPECT_EQ(refusal(one_feature(R"({"name":"Old Town"})")),
            "data.geofencing_zones.features[0].properties.name: must be an array of {text, "
            "language} (GBFS v3.0)");
  EXPECT_EQ(refusal(one_feature("{}", R"(,"global_rules":[{"ride_start_allowed":1}])")),
            "data.global_rules[0].ride_start_allowed: must be true or false");
  std::string v2 = one_feature("{}");
  v2.replace(v2.find("\"3.0\""), 5, "\"2.3\"");
  EXPECT_EQ(refusal(v2),
            "version: \"2.3\" is not \"3.0\" (GBFS 2.x rules differ: ride_allowed; convert the "
            "feed first)");
  EXPECT_EQ(refusal("{\"data\":{\"geofencing_zones\":[]}}"),
            "data.geofencing_zones: not a GeoJSON FeatureCollection with a \"features\" array");
  std::string bad_position = one_feature("{}");
  bad_position.replace(bad_position.find("[14.51,46.0]"), 12, "[194.51,46.0]");
  EXPECT_EQ(refusal(bad_position),
            "data.geofencing_zones.features[0].geometry.coordinates[0][0][1]: longitude 194.51 is "
            "not a number in -180..180");
  EXPECT_EQ(refusal("{\"data\":"), "not JSON");
}

TEST(GbfsZones, WhatHasNoEffectOnTheBikeIsReportedWithItsPath) {
  auto r = zone_bundle_from_gbfs(
      one_feature(R"({"rules":[{"ride_start_allowed":true,"ride_end_allowed":false,)"
                  R"("ride_through_allowed":true,"station_parking":false}],"colour":"red"})",
                  R"(,"operator_note":"x")"));
  ASSERT_TRUE(std::holds_alternative<GbfsZonesImport>(r)) << std::get<std::string>(r);
  EXPECT_EQ(std::get<GbfsZonesImport>(r).notes,
            (std::vector<std::string>{
                "data.operator_note: unknown member, ignored",
                "data.geofencing_zones.features[0].properties.colour: unknown property, ignored "
                "(no effect on the bike)",
                "data.geofencing_zones.features[0].properties.rules[0].station_parking: false "
                "requires nothing; not kept"}));
}

TEST(GbfsZones, AnOlderBundleIsWrittenAsTheRulesTheBikeEnforcesMostRestrictiveFirst) {
  v1::ZoneBundle b;
  b.set_version(3);
  b.set_issued_at_us(*us_from_rfc3339("2026-11-29T09:30:00.250Z"));
  auto add = [&](const std::string& id, v1::ZoneKind kind, std::uint32_t limit = 0) {
    auto* z = b.add_zones();
    z->set_id(id);
    z->set_kind(kind);
    z->set_speed_limit_kmh(limit);
    auto* ring = z->add_rings();
    for (auto [lat, lon] :
         {std::pair{460000000, 145000000}, {460000000, 145100000}, {460100000, 145100000}}) {
      ring->add_lat_e7(lat);
      ring->add_lon_e7(lon);
    }
  };
  add("city", v1::ZONE_KIND_OPERATING_AREA);
  add("old-town", v1::ZONE_KIND_SLOW, 15);
  add("square", v1::ZONE_KIND_SLOW, 10);
  add("station", v1::ZONE_KIND_NO_PARKING);
  add("bridge", v1::ZONE_KIND_NO_RIDE);
  const json doc = gbfs_from_zone_bundle(b);
  EXPECT_EQ(doc["last_updated"], "2026-11-29T09:30:00.250000Z");
  EXPECT_EQ(doc["version"], "3.0");
  const json& f = doc["data"]["geofencing_zones"]["features"];
  ASSERT_EQ(f.size(), 5u);
  std::vector<std::string> ids;
  for (const auto& feature : f) ids.push_back(feature["id"]);
  EXPECT_EQ(ids, (std::vector<std::string>{"bridge", "square", "old-town", "station", "city"}));
  EXPECT_EQ(f[0]["properties"]["rules"][0]["ride_through_allowed"], false);
  EXPECT_EQ(f[1]["properties"]["rules"][0]["maximum_speed_kph"], 10);
  EXPECT_EQ(f[3]["properties"]["rules"][0]["ride_end_allowed"], false);
  // The ring closed as GBFS requires.
  const json& ring = f[4]["geometry"]["coordinates"][0][0];
  ASSERT_EQ(ring.size(), 4u);
  EXPECT_EQ(ring.front(), ring.back());
  EXPECT_EQ(doc["data"]["global_rules"].size(), 1u);  // outside the operating area
}

TEST(GbfsZones, TimestampsAreRfc3339InBothDirections) {
  EXPECT_EQ(us_from_rfc3339("1970-01-01T00:00:00Z"), 0);
  EXPECT_EQ(us_from_rfc3339("2026-11-29T10:00:00+01:00"), *us_from_rfc3339("2026-11-29T09:00:00Z"));
  EXPECT_EQ(us_from_rfc3339("2024-02-29T12:00:00.5Z"), 1'709'208'000'500'000);
  EXPECT_EQ(rfc3339_from_us(1'709'208'000'500'000), "2024-02-29T12:00:00.500000Z");
  EXPECT_EQ(rfc3339_from_us(*us_from_rfc3339("2099-12-31T23:00:00Z")), "2099-12-31T23:00:00Z");
  for (const char* bad : {"2026-13-01T00:00:00Z", "2026-11-29 10:00", "2026-11-29T10:00:00",
                          "2026-11-29T10:00:00Zjunk", "2026-11-29T10:00:00.Z"}) {
    EXPECT_FALSE(us_from_rfc3339(bad)) << bad;
  }
}

}  // namespace
}  // namespace fleetgw::convert
