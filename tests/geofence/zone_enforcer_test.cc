// ZoneEnforcer: the engine's demands as MC writes, one at a time, the speed limit always the
// SpeedAuthority's limit in force (issue 24); and the zone event payload as it goes on the wire.
#include "gateway/geofence/zone_enforcer.h"

#include <gtest/gtest.h>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_payload.h"

namespace fleetgw::geofence {
namespace {

using std::chrono::seconds;

const Micros kT = seconds(1'790'000'000);

Demands limit(std::optional<int> kmh, int cap = 100) {
  Demands d;
  d.speed_limit_kmh = kmh;
  d.assist_cap_percent = cap;
  return d;
}

McWrite speed(int kmh) {
  return {McWrite::Kind::kSpeedLimit, kmh, {}};
}
McWrite assist(std::string level) {
  return {McWrite::Kind::kAssistLevel, 0, std::move(level)};
}

TEST(ZoneEnforcer, ARampIsWrittenStepByStepAndLeavingRestoresTheOperatorsCapExactly) {
  SpeedAuthority authority(25);
  authority.set_operator_cap(22);  // an operator's 22 km/h cap, already on the MC
  ZoneEnforcer e(EnforcerConfig{.speed = &authority});
  McView mc{.speed_limit_kmh = 22, .assist_level = "eco"};
  EXPECT_FALSE(e.next(limit(std::nullopt), mc, kT));  // no zone: 22 is in force already
  // The ramp from 25 never raises the operator's 22.
  for (int kmh = 25; kmh >= 22; --kmh) EXPECT_FALSE(e.next(limit(kmh), mc, kT)) << kmh;
  for (int kmh = 21; kmh >= 15; --kmh) {
    const auto w = e.next(limit(kmh), mc, kT);
    ASSERT_TRUE(w) << kmh;
    EXPECT_EQ(*w, speed(kmh));
    EXPECT_FALSE(e.next(limit(kmh), mc, kT)) << "one write at a time";
    e.on_result(true, kT);
    mc.speed_limit_kmh = kmh;  // the MC's read-back
    EXPECT_FALSE(e.next(limit(kmh), mc, kT));
  }
  EXPECT_EQ(e.applied_limit(), 15);
  // The zone's restore ramp goes up to 25: the limit in force stops at 22, then stays.
  for (int kmh = 16; kmh <= 25; ++kmh) {
    if (const auto w = e.next(limit(kmh), mc, kT)) {
      EXPECT_LE(w->speed_limit_kmh, 22);
      e.on_result(true, kT);
      mc.speed_limit_kmh = w->speed_limit_kmh;
    }
  }
  EXPECT_EQ(mc.speed_limit_kmh, 22);
  EXPECT_FALSE(e.next(limit(std::nullopt), mc, kT));
}

TEST(ZoneEnforcer, WithTheMcsLimitUnknownTheRampStartsBelowTheBikesOwnLimit) {
  ZoneEnforcer e(EnforcerConfig{.own_limit_kmh = 25});
  McView mc{.speed_limit_kmh = std::nullopt, .assist_level = "eco"};
  EXPECT_FALSE(e.next(limit(25), mc, kT));  // the ramp's first step: what is in force already
  EXPECT_EQ(e.next(limit(24), mc, kT), speed(24));
  e.on_result(true, kT);
  EXPECT_FALSE(e.next(limit(24), mc, kT));  // written, the MC's read-back unknown: not again
  EXPECT_EQ(e.next(limit(std::nullopt), mc, kT), speed(25));
  e.on_result(true, kT);
  EXPECT_FALSE(e.next(limit(std::nullopt), mc, kT));
  EXPECT_EQ(e.applied_limit(), 25);
}

TEST(ZoneEnforcer, WithoutACapOrAZoneTheMcsLimitIsLeftAlone) {
  // A limit the gateway never decided (set before issue 24, or by the bike's maker) is not
  // overwritten at start-up.
  ZoneEnforcer e(EnforcerConfig{.own_limit_kmh = 25});
  McView mc{.speed_limit_kmh = 18, .assist_level = "eco"};
  EXPECT_FALSE(e.next(limit(std::nullopt), mc, kT));
  EXPECT_FALSE(e.speed().manages());
}

TEST(ZoneEnforcer, AnOperatorCapInsideAZoneIsNeverWrittenAboveTheZone) {
  SpeedAuthority authority(25);
  ZoneEnforcer e(EnforcerConfig{.speed = &authority});
  McView mc{.speed_limit_kmh = 12, .assist_level = "eco"};
  EXPECT_FALSE(e.next(limit(12), mc, kT));
  authority.set_operator_cap(25);  // "limit 25" inside the 12 km/h zone
  EXPECT_FALSE(e.next(limit(12), mc, kT));
  authority.set_operator_cap(10);  // lower than the zone: the cap decides
  EXPECT_EQ(e.next(limit(12), mc, kT), speed(10));
  e.on_result(true, kT);
  mc.speed_limit_kmh = 10;
  EXPECT_FALSE(e.next(limit(12), mc, kT));
  authority.set_operator_cap(20);
  EXPECT_EQ(e.next(limit(12), mc, kT), speed(12));  // back to the zone's, not the cap's 20
}

TEST(ZoneEnforcer, ABusyMcSkipsRampStepsAndAFailureWaitsBeforeRetrying) {
  ZoneEnforcer e(EnforcerConfig{.retry_after = seconds(5)});
  McView mc{.speed_limit_kmh = 25, .assist_level = "eco", .busy = true};
  EXPECT_FALSE(e.next(limit(24), mc, kT));
  EXPECT_FALSE(e.next(limit(23), mc, kT));
  mc.busy = false;
  EXPECT_EQ(e.next(limit(20), mc, kT), speed(20));  // the latest, not 24 and 23 first
  e.on_result(false, kT);
  EXPECT_FALSE(e.next(limit(19), mc, kT + seconds(4)));
  EXPECT_EQ(e.next(limit(19), mc, kT + seconds(5)), speed(19));
}

TEST(ZoneEnforcer, TheAssistFadesLevelByLevelAndTheRidersLevelComesBack) {
  ZoneEnforcer e;
  McView mc{.speed_limit_kmh = 25, .assist_level = "turbo"};
  std::vector<std::string> written;
  for (int cap = 100; cap >= 0; cap -= 5) {
    if (auto w = e.next(limit(std::nullopt, cap), mc, kT)) {
      ASSERT_EQ(w->kind, McWrite::Kind::kAssistLevel);
      written.push_back(w->assist_level);
      e.on_result(true, kT);
      mc.assist_level = w->assist_level;
    }
  }
  EXPECT_EQ(written, (std::vector<std::string>{"sport", "norm", "eco", "off"}));
  EXPECT_FALSE(e.next(limit(std::nullopt, 50), mc, kT));  // rising: nothing until 100
  EXPECT_EQ(e.next(limit(std::nullopt, 100), mc, kT), assist("turbo"));
  e.on_result(true, kT);
  mc.assist_level = "turbo";
  EXPECT_FALSE(e.next(limit(std::nullopt, 100), mc, kT));
}

TEST(ZoneEnforcer, WalkAssistIsCappedAndALevelTheRiderChoseIsKept) {
  ZoneEnforcer e;
  McView mc{.speed_limit_kmh = std::nullopt, .assist_level = "walk"};
  EXPECT_EQ(e.next(limit(std::nullopt, 0), mc, kT), assist("off"));
  e.on_result(true, kT);
  mc.assist_level = "off";
  // Left the zone, but the rider picked "eco" themselves meanwhile: theirs stays.
  mc.assist_level = "eco";
  EXPECT_FALSE(e.next(limit(std::nullopt, 100), mc, kT));
  EXPECT_FALSE(e.next(limit(std::nullopt, 100), mc, kT));
}

TEST(ZonePayload, AnEventCarriesEverythingAndNoPositionWhenUnknown) {
  ZoneEvent ev;
  ev.zone_id = "old-town";
  ev.zone_name = "Altstadt";
  ev.kind = ZoneKind::kSlow;
  ev.transition = Transition::kEnter;
  ev.at = kT;
  ev.bundle_version = 9;
  ev.speed_limit_kmh = 15;
  gnss::Fix p;
  p.lat_deg = 52.52;
  p.lon_deg = 13.405;
  p.hdop = 0.9;
  p.satellites = 7;
  p.fixed_at = kT - seconds(1);
  ev.position = p;
  v1::ZoneEvent m;
  ASSERT_TRUE(m.ParseFromString(zone_event_payload(ev)));
  EXPECT_EQ(m.zone_id(), "old-town");
  EXPECT_EQ(m.zone_name(), "Altstadt");
  EXPECT_EQ(m.kind(), v1::ZONE_KIND_SLOW);
  EXPECT_EQ(m.transition(), v1::ZONE_TRANSITION_ENTER);
  EXPECT_EQ(m.at_us(), kT.count());
  EXPECT_EQ(m.bundle_version(), 9u);
  EXPECT_EQ(m.speed_limit_kmh(), 15u);
  ASSERT_TRUE(m.has_position());
  EXPECT_EQ(m.position().lat_e7(), 525'200'000);
  EXPECT_EQ(m.position().lon_e7(), 134'050'000);
  EXPECT_EQ(m.position().hdop_centi(), 90u);
  EXPECT_EQ(m.position().satellites(), 7u);
  ev.position.reset();
  ev.transition = Transition::kExit;
  ASSERT_TRUE(m.ParseFromString(zone_event_payload(ev)));
  EXPECT_FALSE(m.has_position());
  EXPECT_EQ(m.transition(), v1::ZONE_TRANSITION_EXIT);
}

}  // namespace
}  // namespace fleetgw::geofence
