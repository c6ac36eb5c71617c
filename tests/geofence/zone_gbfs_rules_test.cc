// The engine with GBFS bundles (issue 27): the city file's rules applied by GBFS precedence (the
// first listed zone wins where zones overlap; UNION, the older meaning, gives the lowest limit),
// for the bike's vehicle type only, within each zone's time window on the engine's clock (a
// window opening and closing around a parked bike), global_rules outside every zone, a limit
// of 0 fading the assistance, and no-start zones refusing an unlock that starts a ride.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "gateway/geofence/zone_bundle.h"
#include "gateway/geofence/zone_engine.h"
#include "proto/convert/gbfs_zones.h"

namespace fleetgw::geofence {
namespace {

using std::chrono::seconds;

// 2026-09-21: inside the city file's festival window (2024-2099), after its 2020 market.
const Micros kGbfsNow = seconds(1'790'000'000);
constexpr double kGbfsLon = 14.5060;  // the file's north-south axis
constexpr double kGbfsLat0 = 46.0560;

std::string city_gbfs() {
  std::ifstream in(std::string(FLEETGW_SOURCE_DIR) +
                   "/tests/geofence/data/ljubljana_geofencing_zones.json");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::shared_ptr<const ZoneSet> gbfs_compiled(
    const std::string& gbfs, v1::ZonePrecedence precedence = v1::ZONE_PRECEDENCE_FIRST_MATCH) {
  auto imported = convert::zone_bundle_from_gbfs(gbfs);
  if (auto* e = std::get_if<std::string>(&imported)) throw std::runtime_error(*e);
  v1::ZoneBundle b = std::get<convert::GbfsZonesImport>(imported).bundle;
  b.set_version(1);
  b.set_issued_at_us(kGbfsNow.count());
  b.set_precedence(precedence);
  if (precedence == v1::ZONE_PRECEDENCE_UNION) b.clear_default_rules();
  auto set = compile_zones(b);
  if (auto* e = std::get_if<std::string>(&set)) throw std::runtime_error(*e);
  return std::make_shared<const ZoneSet>(std::move(std::get<ZoneSet>(set)));
}

gnss::Fix gbfs_at(double north_deg, double east_deg = 0, Micros when = kGbfsNow) {
  gnss::Fix p;
  p.lat_deg = kGbfsLat0 + north_deg;
  p.lon_deg = kGbfsLon + east_deg;
  p.fixed_at = p.received_at = when;
  return p;
}

EngineConfig gbfs_engine_config(std::string type) {
  EngineConfig c;
  c.margin_m = 5;
  c.min_dwell = seconds(0);
  c.speed_ramp = seconds(2);
  c.assist_fade = seconds(2);
  c.restore_ramp = seconds(2);
  c.refuse_ride_ending_locks = true;
  c.vehicle_type_id = std::move(type);
  return c;
}

// What the bike is held to at `where`, once the ramps have settled.
Demands gbfs_settled_at(const std::shared_ptr<const ZoneSet>& zones, const gnss::Fix& where,
                        const std::string& type = "city-ebike") {
  ZoneEngine engine(gbfs_engine_config(type));
  std::vector<ZoneEvent> events;
  engine.set_zones(zones, kGbfsNow, events);
  engine.relocate(kGbfsNow, where, events);
  return engine.demands(kGbfsNow + seconds(10));
}

TEST(ZoneGbfsRules, TheCityFileAppliesByGbfsOrderForTheBikesTypeWithinItsWindows) {
  const auto city = gbfs_compiled(city_gbfs());
  // The station forecourt: no ride may start; no limit.
  const auto station = gbfs_settled_at(city, gbfs_at(0.0001));
  EXPECT_TRUE(station.in_no_start_zone);
  EXPECT_FALSE(station.in_no_parking_zone);
  EXPECT_EQ(station.speed_limit_kmh, std::nullopt);
  // The old town, where the 2020 market (5 km/h, listed earlier) is long over: 12 km/h for a
  // city e-bike, 6 for a cargo bike, whose rule comes first in the feature.
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0030)).speed_limit_kmh, 12);
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0030), "cargo-ebike").speed_limit_kmh, 6);
  // Slovenska cesta, listed before the old town it crosses: its 20 km/h, not the lower 12.
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0050)).speed_limit_kmh, 20);
  // The festival (in its window, listed first): 8.
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0070)).speed_limit_kmh, 8);
  // The service area alone: nothing; Tivoli park: no parking; Presernov trg: the assistance off.
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0100)), Demands{});
  EXPECT_TRUE(gbfs_settled_at(city, gbfs_at(0.0030, -0.0040)).in_no_parking_zone);
  EXPECT_EQ(gbfs_settled_at(city, gbfs_at(0.0085, 0.0035)).assist_cap_percent, 0);
  // Outside every zone: global_rules (15 km/h, neither start nor end).
  const auto outside = gbfs_settled_at(city, gbfs_at(0.0200));
  EXPECT_EQ(outside.speed_limit_kmh, 15);
  EXPECT_TRUE(outside.in_no_start_zone);
  EXPECT_TRUE(outside.in_no_parking_zone);

  // The same zones under the older UNION meaning: the lowest limit of every zone (the expired
  // market still out of its window).
  const auto as_union = gbfs_compiled(city_gbfs(), v1::ZONE_PRECEDENCE_UNION);
  EXPECT_EQ(gbfs_settled_at(as_union, gbfs_at(0.0050)).speed_limit_kmh, 12);
  EXPECT_EQ(gbfs_settled_at(as_union, gbfs_at(0.0070)).speed_limit_kmh, 8);
  EXPECT_EQ(gbfs_settled_at(as_union, gbfs_at(0.0200)), Demands{});
}

// Two overlapping features with different limits: GBFS order decides, both ways round.
std::string gbfs_two_overlapping(int first_kmh, int second_kmh) {
  auto feature = [](double west, int kmh) {
    char ring[200];
    std::snprintf(ring, sizeof ring,
                  "[[[[%.4f,46.0],[%.4f,46.0],[%.4f,46.01],[%.4f,46.01],"
                  "[%.4f,46.0]]]]",
                  west, west + 0.01, west + 0.01, west, west);
    return std::string(R"({"type":"Feature","geometry":{"type":"MultiPolygon","coordinates":)") +
           ring +
           R"(},"properties":{"rules":[{"ride_start_allowed":true,"ride_end_allowed":true,)"
           R"("ride_through_allowed":true,"maximum_speed_kph":)" +
           std::to_string(kmh) + "}]}}";
  };
  return R"({"version":"3.0","data":{"geofencing_zones":{"type":"FeatureCollection",)"
         R"("features":[)" +
         feature(14.500, first_kmh) + "," + feature(14.505, second_kmh) +
         R"(]},"global_rules":[]}})";
}

TEST(ZoneGbfsRules, OverlappingZonesResolveByGbfsOrderNotByTheLowestLimit) {
  gnss::Fix overlap, first_only, second_only;
  overlap.lat_deg = first_only.lat_deg = second_only.lat_deg = 46.005;
  overlap.lon_deg = 14.5075;
  first_only.lon_deg = 14.502;
  second_only.lon_deg = 14.513;
  const auto fast_first = gbfs_compiled(gbfs_two_overlapping(20, 10));
  EXPECT_EQ(gbfs_settled_at(fast_first, overlap).speed_limit_kmh, 20);
  EXPECT_EQ(gbfs_settled_at(fast_first, first_only).speed_limit_kmh, 20);
  EXPECT_EQ(gbfs_settled_at(fast_first, second_only).speed_limit_kmh, 10);
  const auto slow_first = gbfs_compiled(gbfs_two_overlapping(10, 20));
  EXPECT_EQ(gbfs_settled_at(slow_first, overlap).speed_limit_kmh, 10);
  EXPECT_EQ(gbfs_settled_at(slow_first, second_only).speed_limit_kmh, 20);
  // The older meaning, kept for UNION bundles: the lowest limit wherever they overlap.
  EXPECT_EQ(gbfs_settled_at(gbfs_compiled(gbfs_two_overlapping(20, 10), v1::ZONE_PRECEDENCE_UNION),
                            overlap)
                .speed_limit_kmh,
            10);
}

TEST(ZoneGbfsRules, AnExpiredWindowWouldHaveAppliedInItsTime) {
  // On 2020-12-24 the market (listed before the old town) is in force: 5 km/h, no parking.
  const auto city = gbfs_compiled(city_gbfs());
  const Micros christmas = seconds(1'608'811'200);
  ZoneEngine engine(gbfs_engine_config("city-ebike"));
  std::vector<ZoneEvent> events;
  engine.set_zones(city, christmas, events);
  engine.relocate(christmas, gbfs_at(0.0030, 0, christmas), events);
  const auto d = engine.demands(christmas + seconds(10));
  EXPECT_EQ(d.speed_limit_kmh, 5);
  EXPECT_TRUE(d.in_no_parking_zone);
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().zone_id, "gbfs-1");
}

std::string gbfs_windowed(Micros start, Micros end, int limit) {
  return R"({"last_updated":"2026-11-29T08:00:00Z","ttl":0,"version":"3.0","data":{
    "geofencing_zones":{"type":"FeatureCollection","features":[{"type":"Feature",
      "geometry":{"type":"MultiPolygon","coordinates":[[[[14.5,46.0],[14.51,46.0],[14.51,46.01],
        [14.5,46.01],[14.5,46.0]]]]},
      "properties":{"start":")" +
         convert::rfc3339_from_us(start.count()) + R"(","end":")" +
         convert::rfc3339_from_us(end.count()) +
         R"(","rules":[{"ride_start_allowed":true,"ride_end_allowed":true,)"
         R"("ride_through_allowed":true,"maximum_speed_kph":)" +
         std::to_string(limit) + R"(}]}}]},"global_rules":[]}})";
}

TEST(ZoneGbfsRules, AWindowOpensAndClosesAroundAParkedBikeOnTheEnginesClock) {
  const auto zones =
      gbfs_compiled(gbfs_windowed(kGbfsNow + seconds(60), kGbfsNow + seconds(120), 10));
  ZoneEngine engine(gbfs_engine_config(""));
  std::vector<ZoneEvent> events;
  engine.set_zones(zones, kGbfsNow, events);
  gnss::Fix inside;
  inside.lat_deg = 46.005;
  inside.lon_deg = 14.505;
  engine.relocate(kGbfsNow, inside, events);
  EXPECT_TRUE(events.empty()) << "not in force yet: silent";
  EXPECT_EQ(engine.demands(kGbfsNow).speed_limit_kmh, std::nullopt);
  // The owner is woken for the window's start, with no fix coming.
  EXPECT_EQ(engine.next_change(kGbfsNow), kGbfsNow + seconds(60));
  engine.advance(kGbfsNow + seconds(59), events);
  EXPECT_TRUE(events.empty());
  engine.advance(kGbfsNow + seconds(60), events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].transition, Transition::kEnter);
  EXPECT_EQ(events[0].at, kGbfsNow + seconds(60));
  EXPECT_EQ(events[0].speed_limit_kmh, 10);
  EXPECT_EQ(engine.demands(kGbfsNow + seconds(63)).speed_limit_kmh, 10);
  EXPECT_EQ(engine.next_change(kGbfsNow + seconds(63)), kGbfsNow + seconds(120));
  engine.advance(kGbfsNow + seconds(120), events);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].transition, Transition::kExit);
  EXPECT_EQ(engine.demands(kGbfsNow + seconds(130)).speed_limit_kmh, std::nullopt);
  EXPECT_EQ(engine.next_change(kGbfsNow + seconds(130)), std::nullopt);
}

TEST(ZoneGbfsRules, ALimitOfZeroFadesTheAssistanceAndNeverWritesZero) {
  const auto zones =
      gbfs_compiled(gbfs_windowed(kGbfsNow - seconds(10), kGbfsNow + seconds(3600), 0));
  gnss::Fix inside;
  inside.lat_deg = 46.005;
  inside.lon_deg = 14.505;
  const auto d = gbfs_settled_at(zones, inside);
  EXPECT_EQ(d.assist_cap_percent, 0);
  EXPECT_EQ(d.speed_limit_kmh, std::nullopt);
}

TEST(ZoneGbfsRules, AnUnlockStartingARideIsRefusedClearlyInsideANoStartZoneOnly) {
  const auto city = gbfs_compiled(city_gbfs());
  ZoneEngine engine(gbfs_engine_config("city-ebike"));
  std::vector<ZoneEvent> events;
  engine.set_zones(city, kGbfsNow, events);
  const auto station = gbfs_at(0.0001);
  const auto v = engine.starting(&station, true, kGbfsNow);
  EXPECT_TRUE(v.refuse);
  ASSERT_TRUE(v.event);
  EXPECT_EQ(v.event->zone_id, "gbfs-4");
  EXPECT_EQ(v.event->zone_name, "Železniška postaja");
  EXPECT_EQ(v.event->transition, Transition::kUnlockRefused);
  // An unlock that starts no ride (a seat lock), an unknown position, a fix within the margin
  // of the forecourt's edge, the old town: never refused.
  EXPECT_FALSE(engine.starting(&station, false, kGbfsNow).refuse);
  EXPECT_FALSE(engine.starting(nullptr, true, kGbfsNow).refuse);
  const auto edge = gbfs_at(0.0004 - 0.00002);  // ~2 m inside the north edge, margin 5 m
  EXPECT_FALSE(engine.starting(&edge, true, kGbfsNow).refuse);
  const auto old_town = gbfs_at(0.0030);
  EXPECT_FALSE(engine.starting(&old_town, true, kGbfsNow).refuse);
  // Outside the service area global_rules forbid starting: refused, named as GBFS names them.
  const auto outside = gbfs_at(0.0200);
  const auto g = engine.starting(&outside, true, kGbfsNow);
  EXPECT_TRUE(g.refuse);
  ASSERT_TRUE(g.event);
  EXPECT_EQ(g.event->zone_id, "global_rules");
  // Parking there too: refused (configured), where the old town allows it.
  EXPECT_TRUE(engine.parking(&outside, true, kGbfsNow).refuse);
  EXPECT_FALSE(engine.parking(&old_town, true, kGbfsNow).in_no_parking_zone);
}

}  // namespace
}  // namespace fleetgw::geofence
