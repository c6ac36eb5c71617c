// ZoneEngine: enter/exit with hysteresis and dwell, no transitions on an unknown position, the
// slow-zone ramp down and restore, the no-ride fade, operating-area alarm, no-parking locks.
#include "gateway/geofence/zone_engine.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/geofence/zone_test_util.h"

namespace fleetgw::geofence {
namespace {

using namespace testing;
using std::chrono::milliseconds;
using std::chrono::seconds;

const Micros t0 = seconds(1'790'000'000);

EnforcedZone make_zone(std::string id, ZoneKind kind, std::vector<Ring> rings, int limit = 0) {
  return EnforcedZone{id, "zone " + id, kind, limit, ZonePolygon::build(rings), {}, Micros(0), Micros(0)};
}

std::shared_ptr<const ZoneSet> set_of(std::vector<EnforcedZone> zones, std::uint64_t version = 1) {
  auto s = std::make_shared<ZoneSet>();
  s->version = version;
  s->issued_at = t0;
  s->zones = std::move(zones);
  return s;
}

// A square slow zone of 15 km/h, 400 m wide, centred on the origin.
std::shared_ptr<const ZoneSet> slow_square(int limit = 15) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("slow", ZoneKind::kSlow, {rect(-200, -200, 200, 200)}, limit));
  return set_of(std::move(zones));
}

struct Driver {
  ZoneEngine engine;
  std::vector<ZoneEvent> events;
  Demands last;

  explicit Driver(EngineConfig c = {}) : engine(c) {}
  Demands at(double east, double north, Micros now) {
    const auto p = fix_at(east, north, now);
    return last = engine.step(now, &p, events);
  }
  Demands unknown(Micros now) { return last = engine.step(now, nullptr, events); }
};

TEST(ZoneEngine, EnteringAfterTheDwellRampsTheLimitDownAndLeavingRestoresIt) {
  Driver d(EngineConfig{.margin_m = 10,
                        .min_dwell = seconds(3),
                        .speed_ramp = seconds(10),
                        .restore_ramp = seconds(5),
                        .unrestricted_kmh = 25});
  d.engine.set_zones(slow_square(15), t0, d.events);
  // Outside: nothing.
  for (int s = 0; s < 5; ++s) d.at(-400, 0, t0 + seconds(s));
  EXPECT_TRUE(d.events.empty());
  EXPECT_FALSE(d.last.speed_limit_kmh);
  // Clearly inside from t=10 s: the dwell holds the entry until 13 s.
  d.at(0, 0, t0 + seconds(10));
  d.at(0, 0, t0 + seconds(12));
  EXPECT_TRUE(d.events.empty());
  EXPECT_FALSE(d.last.speed_limit_kmh);
  d.at(0, 0, t0 + seconds(13));
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].transition, Transition::kEnter);
  EXPECT_EQ(d.events[0].zone_id, "slow");
  EXPECT_EQ(d.events[0].speed_limit_kmh, 15);
  ASSERT_TRUE(d.events[0].position);
  const Micros entered = t0 + seconds(13);
  // Down the ramp: 25 -> 15 over 10 s, never below the straight line, never a jump of more
  // than one km/h per second.
  int previous = 25;
  for (int ms = 0; ms <= 10'000; ms += 250) {
    const Micros now = entered + milliseconds(ms);
    const auto limit = d.engine.demands(now).speed_limit_kmh;
    ASSERT_TRUE(limit) << ms;
    const double line = 25.0 - 10.0 * ms / 10'000.0;
    EXPECT_GE(*limit, line - 1e-9) << ms;
    EXPECT_LT(*limit, line + 1.0) << ms;
    EXPECT_LE(*limit, previous);
    EXPECT_GE(*limit, previous - 1);
    previous = *limit;
  }
  EXPECT_EQ(d.engine.demands(entered + seconds(5)).speed_limit_kmh, 20);
  EXPECT_EQ(d.engine.demands(entered + seconds(10)).speed_limit_kmh, 15);
  EXPECT_FALSE(d.engine.next_change(entered + seconds(10)));
  // The owner is woken for each whole step of the ramp: 10 steps.
  int wakeups = 0;
  for (auto t = d.engine.next_change(entered); t; t = d.engine.next_change(*t)) ++wakeups;
  EXPECT_EQ(wakeups, 10);
  // Leave: clearly outside from 30 s, the exit at 33 s, then back up to 25 over 5 s and no
  // zone limit at all.
  d.events.clear();
  d.at(-400, 0, t0 + seconds(30));
  EXPECT_TRUE(d.events.empty());
  EXPECT_EQ(d.last.speed_limit_kmh, 15);
  d.at(-400, 0, t0 + seconds(33));
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].transition, Transition::kExit);
  EXPECT_EQ(d.engine.demands(t0 + seconds(35)).speed_limit_kmh, 19);
  EXPECT_EQ(d.engine.demands(t0 + seconds(38)).speed_limit_kmh, std::nullopt);
}

TEST(ZoneEngine, AWobblingTrackAlongABoundaryDoesNotFlap) {
  // Ten minutes at 1 Hz riding slowly along the zone's east edge (x = 200), GNSS noise of
  // +-12 m across it: a sixth of the fixes are beyond the 10 m margin on one side or the
  // other, never for the dwell time on end.
  auto run = [](EngineConfig c) {
    Driver d(c);
    d.engine.set_zones(slow_square(15), t0, d.events);
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> noise(-12, 12);
    for (int s = 0; s < 600; ++s) d.at(200 + noise(rng), -150 + s * 0.5, t0 + seconds(s));
    return d.events.size();
  };
  EXPECT_EQ(run(EngineConfig{.margin_m = 10, .min_dwell = seconds(3)}), 0u);
  // The same track without hysteresis or dwell flaps: the test can tell.
  EXPECT_GT(run(EngineConfig{.margin_m = 0, .min_dwell = Micros(0)}), 50u);
}

TEST(ZoneEngine, AShortExcursionShorterThanTheDwellIsNoTransition) {
  Driver d;
  d.engine.set_zones(slow_square(), t0, d.events);
  for (int s = 0; s < 5; ++s) d.at(0, 0, t0 + seconds(s));
  ASSERT_EQ(d.events.size(), 1u);  // entered at 3 s
  d.events.clear();
  d.at(-400, 0, t0 + seconds(10));
  d.at(-400, 0, t0 + seconds(12));  // 2 s out
  d.at(0, 0, t0 + seconds(13));     // back: the dwell starts over
  d.at(-400, 0, t0 + seconds(14));
  d.at(-400, 0, t0 + seconds(16));
  EXPECT_TRUE(d.events.empty());
  d.at(-400, 0, t0 + seconds(17));
  EXPECT_EQ(d.events.size(), 1u);
}

TEST(ZoneEngine, AnUnknownPositionChangesNothingAndInterruptsTheDwell) {
  Driver d;
  d.engine.set_zones(slow_square(), t0, d.events);
  for (int s = 0; s <= 30; ++s) d.at(0, 0, t0 + seconds(s));
  ASSERT_EQ(d.events.size(), 1u);
  ASSERT_EQ(d.last.speed_limit_kmh, 15);
  d.events.clear();
  // A tunnel: ten minutes without a position. The zone stays applied.
  for (int s = 31; s < 600; ++s) d.unknown(t0 + seconds(s));
  EXPECT_TRUE(d.events.empty());
  EXPECT_EQ(d.last.speed_limit_kmh, 15);
  EXPECT_EQ(d.engine.inside(0), true);
  // Outside, unknown, outside: the gap restarts the dwell.
  d.at(-400, 0, t0 + seconds(600));
  d.at(-400, 0, t0 + seconds(602));
  d.unknown(t0 + seconds(603));
  d.at(-400, 0, t0 + seconds(604));
  d.at(-400, 0, t0 + seconds(606));
  EXPECT_TRUE(d.events.empty());
  d.at(-400, 0, t0 + seconds(607));
  EXPECT_EQ(d.events.size(), 1u);
}

TEST(ZoneEngine, TheLowestLimitOfOverlappingSlowZonesWins) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("wide", ZoneKind::kSlow, {rect(-500, -500, 500, 500)}, 20));
  zones.push_back(make_zone("core", ZoneKind::kSlow, {rect(-100, -100, 100, 100)}, 12));
  Driver d(
      EngineConfig{.min_dwell = Micros(0), .speed_ramp = Micros(0), .restore_ramp = Micros(0)});
  d.engine.set_zones(set_of(std::move(zones)), t0, d.events);
  EXPECT_EQ(d.at(300, 0, t0).speed_limit_kmh, 20);
  EXPECT_EQ(d.at(0, 0, t0 + seconds(1)).speed_limit_kmh, 12);
  EXPECT_EQ(d.at(300, 0, t0 + seconds(2)).speed_limit_kmh, 20);
  EXPECT_EQ(d.at(900, 0, t0 + seconds(3)).speed_limit_kmh, std::nullopt);
  EXPECT_EQ(d.events.size(), 4u);  // enter wide, enter core, exit core, exit wide
}

TEST(ZoneEngine, ANoRideZoneFadesTheAssistanceNeverAtOnce) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("park", ZoneKind::kNoRide, {rect(-200, -200, 200, 200)}));
  Driver d(
      EngineConfig{.min_dwell = seconds(2), .assist_fade = seconds(8), .restore_ramp = seconds(4)});
  d.engine.set_zones(set_of(std::move(zones)), t0, d.events);
  d.at(0, 0, t0);
  EXPECT_EQ(d.at(0, 0, t0 + seconds(2)).assist_cap_percent, 100);
  ASSERT_EQ(d.events.size(), 1u);
  int previous = 100;
  for (int ms = 0; ms <= 8000; ms += 100) {
    const int cap = d.engine.demands(t0 + seconds(2) + milliseconds(ms)).assist_cap_percent;
    EXPECT_LE(previous - cap, 2) << "a jump at " << ms << " ms";
    EXPECT_GE(cap, 100 - ms * 100 / 8000) << ms;
    previous = cap;
  }
  EXPECT_EQ(d.engine.demands(t0 + seconds(10)).assist_cap_percent, 0);
  EXPECT_FALSE(d.engine.demands(t0 + seconds(10)).speed_limit_kmh);
  d.at(-400, 0, t0 + seconds(20));
  d.at(-400, 0, t0 + seconds(22));
  EXPECT_EQ(d.engine.demands(t0 + seconds(24)).assist_cap_percent, 50);
  EXPECT_EQ(d.engine.demands(t0 + seconds(26)).assist_cap_percent, 100);
}

TEST(ZoneEngine, LeavingTheOperatingAreaRaisesTheAlarmLevelAndAnExitEvent) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("city", ZoneKind::kOperatingArea, {rect(-1000, -1000, 1000, 1000)}));
  zones.push_back(make_zone("airport", ZoneKind::kOperatingArea, {rect(3000, 0, 3500, 500)}));
  Driver d(EngineConfig{.min_dwell = seconds(1)});
  d.engine.set_zones(set_of(std::move(zones)), t0, d.events);
  // Unknown at first: no alarm before anything is known.
  EXPECT_FALSE(d.engine.demands(t0).outside_operating_area);
  d.at(0, 0, t0);
  EXPECT_FALSE(d.at(0, 0, t0 + seconds(1)).outside_operating_area);
  d.at(2000, 0, t0 + seconds(2));
  EXPECT_TRUE(d.at(2000, 0, t0 + seconds(3)).outside_operating_area);
  ASSERT_EQ(d.events.size(), 2u);
  EXPECT_EQ(d.events[1].transition, Transition::kExit);
  EXPECT_EQ(d.events[1].kind, ZoneKind::kOperatingArea);
  d.at(3200, 200, t0 + seconds(4));
  EXPECT_FALSE(d.at(3200, 200, t0 + seconds(5)).outside_operating_area);  // in the other one
}

TEST(ZoneEngine, ABikeSwitchedOnOutsideEveryOperatingAreaIsInAlarmWithoutAnEvent) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("city", ZoneKind::kOperatingArea, {rect(-1000, -1000, 1000, 1000)}));
  Driver d(EngineConfig{.min_dwell = seconds(1)});
  d.engine.set_zones(set_of(std::move(zones)), t0, d.events);
  d.at(5000, 0, t0);
  EXPECT_TRUE(d.at(5000, 0, t0 + seconds(1)).outside_operating_area);
  EXPECT_TRUE(d.events.empty());
}

TEST(ZoneEngine, ALockInANoParkingZoneIsReportedAndRefusedOnlyWhenConfigured) {
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("station", ZoneKind::kNoParking, {rect(-100, -100, 100, 100)}));
  auto set = set_of(std::move(zones));
  const auto inside = fix_at(0, 0, t0);
  const auto edge = fix_at(95, 0, t0);
  const auto outside = fix_at(300, 0, t0);
  std::vector<ZoneEvent> ignored;

  ZoneEngine report_only(EngineConfig{});
  report_only.set_zones(set, t0, ignored);
  auto v = report_only.parking(&inside, true, t0);
  EXPECT_TRUE(v.in_no_parking_zone);
  EXPECT_FALSE(v.refuse);
  ASSERT_TRUE(v.event);
  EXPECT_EQ(v.event->transition, Transition::kLockedInNoParking);
  EXPECT_FALSE(report_only.parking(&outside, true, t0).in_no_parking_zone);

  ZoneEngine refusing(EngineConfig{.refuse_ride_ending_locks = true});
  refusing.set_zones(set, t0, ignored);
  v = refusing.parking(&inside, true, t0);
  EXPECT_TRUE(v.refuse);
  EXPECT_EQ(v.event->transition, Transition::kLockRefused);
  EXPECT_FALSE(refusing.parking(&inside, false, t0).refuse);  // not ending a ride
  v = refusing.parking(&edge, true, t0);                      // within the margin: report only
  EXPECT_TRUE(v.in_no_parking_zone);
  EXPECT_FALSE(v.refuse);
  EXPECT_FALSE(refusing.parking(nullptr, true, t0).refuse);  // unknown: never refused
}

TEST(ZoneEngine, ANewBundleKeepsTheStateOfKeptZonesAndEndsRemovedOnes) {
  Driver d(
      EngineConfig{.min_dwell = Micros(0), .speed_ramp = Micros(0), .restore_ramp = seconds(5)});
  std::vector<EnforcedZone> zones;
  zones.push_back(make_zone("slow", ZoneKind::kSlow, {rect(-200, -200, 200, 200)}, 15));
  zones.push_back(make_zone("park", ZoneKind::kNoRide, {rect(-300, -300, 300, 300)}));
  d.engine.set_zones(set_of(std::move(zones), 1), t0, d.events);
  d.at(0, 0, t0);
  ASSERT_EQ(d.events.size(), 2u);
  d.events.clear();
  // Version 2 keeps "park" and drops "slow": one exit, the limit ramps back up.
  std::vector<EnforcedZone> next;
  next.push_back(make_zone("park", ZoneKind::kNoRide, {rect(-300, -300, 300, 300)}));
  d.engine.set_zones(set_of(std::move(next), 2), t0 + seconds(10), d.events);
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].zone_id, "slow");
  EXPECT_EQ(d.events[0].transition, Transition::kExit);
  EXPECT_EQ(d.events[0].bundle_version, 1u);
  EXPECT_EQ(d.engine.inside(0), true);  // "park", still inside, no new event
  EXPECT_EQ(d.engine.demands(t0 + seconds(15)).speed_limit_kmh, std::nullopt);
  d.at(0, 0, t0 + seconds(16));
  EXPECT_EQ(d.events.size(), 1u);
}

TEST(ZoneEngine, RampStepsAreWholeAndTheirTimesExact) {
  Ramp r(25);
  r.retarget(15, t0, seconds(10));
  EXPECT_EQ(r.whole(t0), 25);
  EXPECT_EQ(r.whole(t0 + milliseconds(999)), 25);
  EXPECT_EQ(r.whole(t0 + milliseconds(1001)), 24);
  const auto next = r.next_step(t0);
  ASSERT_TRUE(next);
  EXPECT_NEAR(static_cast<double>((*next - t0).count()), 1e6, 2);
  EXPECT_EQ(r.whole(*next), 24);
  // Retargeted mid-way: from where it is, not from where it started.
  r.retarget(25, t0 + seconds(5), seconds(5));
  EXPECT_EQ(r.whole(t0 + seconds(5)), 20);
  EXPECT_EQ(r.whole(t0 + seconds(10)), 25);
}

}  // namespace
}  // namespace fleetgw::geofence
