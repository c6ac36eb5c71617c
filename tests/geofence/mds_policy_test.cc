// MDS 2.0 Policy speed rules + Geography -> ZoneBundle (issue 27, proto/convert/mds_policy.h):
// the limits in the policy's rule order (first match), mph rounded down, the policy's dates as
// the zones' window, a rule for scooters only skipped with a note, and what the bike cannot
// enforce (a count rule, a weekly schedule) refused naming the rule and its JSON path.
#include "proto/convert/mds_policy.h"

#include <gtest/gtest.h>

#include "gateway/geofence/zone_bundle.h"

namespace fleetgw::convert {
namespace {

const char* const kMdsGeography = R"({"version":"2.0.0","data":{"geographies":[
  {"geography_id":"8917cf2d-a963-4ea2-a98b-7725050b3ec5","name":"Old Town",
   "geography_json":{"type":"FeatureCollection","features":[{"type":"Feature","properties":{},
     "geometry":{"type":"MultiPolygon","coordinates":[
       [[[14.50,46.05],[14.51,46.05],[14.51,46.06],[14.50,46.06],[14.50,46.05]]],
       [[[14.52,46.05],[14.53,46.05],[14.53,46.06],[14.52,46.05]]]]}}]}},
  {"geography_id":"b4bcc213-4888-48ce-a33d-4dd6c3384bda","name":"City",
   "geography_json":{"type":"Polygon","coordinates":[
     [[14.4,46.0],[14.6,46.0],[14.6,46.1],[14.4,46.1],[14.4,46.0]]]}}]}})";

std::string mds_policy(const std::string& extra_rule = "") {
  return R"({"version":"2.0.0","data":{"policies":[{"policy_id":"95645117-fd85-463e-a2c9",
    "name":"Speed limits","start_date":1767225600000,"end_date":null,"rules":[
    {"name":"Old Town","rule_id":"d4c0","rule_type":"speed","rule_units":"mph",
     "geographies":["8917cf2d-a963-4ea2-a98b-7725050b3ec5"],"states":{"on_trip":[]},
     "vehicle_types":["bicycle","scooter"],"maximum":10,
     "messages":{"en-US":"Stay under 10 MPH"}},
    {"name":"Scooters","rule_id":"e5d1","rule_type":"speed","rule_units":"kph",
     "geographies":["b4bcc213-4888-48ce-a33d-4dd6c3384bda"],"vehicle_types":["scooter"],
     "maximum":12},)" +
         extra_rule +
         R"({"name":"City","rule_id":"529b","rule_type":"speed","rule_units":"kph",
     "geographies":["b4bcc213-4888-48ce-a33d-4dd6c3384bda"],"maximum":20}]}]}})";
}

std::string mds_refusal(const std::string& policy) {
  auto r = zone_bundle_from_mds(policy, kMdsGeography);
  if (auto* e = std::get_if<std::string>(&r)) return *e;
  return "(accepted)";
}

TEST(MdsPolicy, SpeedRulesBecomeRulesZonesInOrderWithThePolicysWindow) {
  auto r = zone_bundle_from_mds(mds_policy(), kMdsGeography);
  ASSERT_TRUE(std::holds_alternative<GbfsZonesImport>(r)) << std::get<std::string>(r);
  auto& imported = std::get<GbfsZonesImport>(r);
  auto& b = imported.bundle;
  EXPECT_EQ(b.precedence(), v1::ZONE_PRECEDENCE_FIRST_MATCH);
  ASSERT_EQ(b.zones_size(), 2);  // the scooters' rule skipped
  EXPECT_EQ(b.zones(0).id(), "mds-0-0-0");
  EXPECT_EQ(b.zones(0).name(), "Old Town / Old Town");
  EXPECT_EQ(b.zones(0).rules(0).maximum_speed_kph(), 16u);  // 10 mph = 16.09 km/h, rounded down
  EXPECT_EQ(std::vector<std::uint32_t>(b.zones(0).polygon_rings().begin(),
                                       b.zones(0).polygon_rings().end()),
            (std::vector<std::uint32_t>{1, 1}));
  EXPECT_EQ(b.zones(0).start_us(), 1'767'225'600'000'000);
  EXPECT_EQ(b.zones(0).end_us(), 0);
  EXPECT_EQ(b.zones(1).id(), "mds-0-2-0");
  EXPECT_EQ(b.zones(1).rules(0).maximum_speed_kph(), 20u);
  EXPECT_EQ(imported.notes,
            (std::vector<std::string>{
                "data.policies[0].rules[0].messages: no effect on the bike (the limit holds in "
                "every state)",
                "data.policies[0].rules[0].states: no effect on the bike (the limit holds in "
                "every state)",
                "data.policies[0].rules[1]: not for bicycles (vehicle_types [\"scooter\"]); "
                "skipped"}));
  b.set_version(1);
  b.set_issued_at_us(1'790'000'000'000'000);
  auto set = geofence::compile_zones(b);
  ASSERT_TRUE(std::holds_alternative<geofence::ZoneSet>(set)) << std::get<std::string>(set);
  // The export writes them as GBFS rules, which a GBFS reader reads with the same precedence.
  const auto gbfs = gbfs_from_zone_bundle(b);
  EXPECT_EQ(gbfs["data"]["geofencing_zones"]["features"][0]["properties"]["rules"][0]
                ["maximum_speed_kph"],
            16);
}

TEST(MdsPolicy, WhatTheBikeCannotEnforceIsRefusedNamingTheRule) {
  EXPECT_EQ(mds_refusal(mds_policy(R"({"name":"Cap","rule_type":"count","maximum":500,
     "geographies":["b4bcc213-4888-48ce-a33d-4dd6c3384bda"]},)")),
            "policy data.policies[0].rules[2].rule_type: \"count\" ('Cap'): only speed rules are "
            "enforced by the bike (refused, not dropped)");
  EXPECT_EQ(mds_refusal(mds_policy(R"({"name":"Weekends","rule_type":"speed","maximum":8,
     "days":["sat","sun"],"geographies":["b4bcc213-4888-48ce-a33d-4dd6c3384bda"]},)")),
            "policy data.policies[0].rules[2].days ('Weekends'): a weekly schedule cannot be "
            "expressed (a zone's window is one interval)");
  EXPECT_EQ(mds_refusal(mds_policy(R"({"name":"Nowhere","rule_type":"speed","maximum":8,
     "geographies":["00000000"]},)")),
            "policy data.policies[0].rules[2].geographies[0]: \"00000000\" is not in the "
            "Geography");
  EXPECT_EQ(mds_refusal(mds_policy(R"({"name":"Fast","rule_type":"speed","maximum":300,
     "geographies":["b4bcc213-4888-48ce-a33d-4dd6c3384bda"]},)")),
            "policy data.policies[0].rules[2].maximum: 300 kph is over 255 km/h");
}

}  // namespace
}  // namespace fleetgw::convert
