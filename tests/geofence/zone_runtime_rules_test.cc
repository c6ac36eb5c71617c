// The geofence rules the runtime relies on beyond the engine's own (docs/location.md, issue 14):
// a bundle replaced at run time is evaluated at the current fix at once (no wait for the next
// fix, no dwell for a zone that is only new), every bundle offered is counted with the latest
// refusal kept for `fleetgw status`, and a lock made on the bike is told apart from a lock
// command and judged once per parking.
#include <gtest/gtest.h>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_controller.h"
#include "gateway/geofence/zone_lock_watch.h"
#include "tests/geofence/zone_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

using namespace testing;
using std::chrono::seconds;

const Micros kRulesStart = seconds(1'790'000'000);

std::span<const std::uint8_t> rules_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

class ZoneRuntimeRules : public ::testing::Test {
 protected:
  fleetgw::testing::TempDir dir{"zone-runtime"};
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();

  ZoneControllerConfig config() {
    ZoneControllerConfig c;
    c.engine.margin_m = 10;
    c.engine.min_dwell = seconds(3);
    c.engine.speed_ramp = seconds(10);
    c.trusted_keys = {{"ops", key.public_key().base64()}};
    c.bundle_file = dir / "zones.pb";
    return c;
  }
  // Version `version`: an operating area 400 m wide centred `area_east_m` east of the origin,
  // and (optionally) a 15 km/h slow zone around the origin.
  std::string bundle(std::uint64_t version, double area_east_m, bool slow = false) {
    v1::ZoneBundle b;
    b.set_version(version);
    b.set_issued_at_us(kRulesStart.count());
    add_zone(b, "city", v1::ZONE_KIND_OPERATING_AREA,
             {rect(area_east_m - 200, -200, area_east_m + 200, 200)});
    if (slow) add_zone(b, "old-town", v1::ZONE_KIND_SLOW, {rect(-100, -100, 100, 100)}, 15);
    return sign_zone_bundle(b, key, "ops");
  }
};

TEST_F(ZoneRuntimeRules, AReplacedBundleIsEvaluatedAtTheCurrentFixAtOnce) {
  ZoneController c(config());
  std::vector<ZoneEvent> events;
  std::string error;
  Micros now = kRulesStart;
  // Version 1: the bike at the origin, inside the area, confirmed after the dwell.
  ASSERT_TRUE(c.on_bundle(rules_bytes(bundle(1, 0)), now, events, error).accepted());
  const auto here = fix_at(0, 0, now);
  c.on_position(now, &here, events);
  now += seconds(3);
  c.on_position(now, &here, events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(c.demands(now).outside_operating_area);
  events.clear();

  // Version 2 moves the area 1 km east and adds a slow zone around the bike. With the current
  // fix given, both apply at the moment the bundle arrives: no further fix, no dwell.
  now += seconds(1);
  const auto v = c.on_bundle(rules_bytes(bundle(2, 1000, true)), now, events, error, &here);
  ASSERT_TRUE(v.accepted()) << v.detail;
  EXPECT_TRUE(c.demands(now).outside_operating_area);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].zone_id, "city");  // the same zone id, moved away from the bike
  EXPECT_EQ(events[0].transition, Transition::kExit);
  EXPECT_EQ(events[1].zone_id, "old-town");
  EXPECT_EQ(events[1].transition, Transition::kEnter);
  EXPECT_EQ(events[1].bundle_version, 2u);
  ASSERT_TRUE(c.demands(now + seconds(10)).speed_limit_kmh);
  EXPECT_EQ(*c.demands(now + seconds(10)).speed_limit_kmh, 15);
}

TEST_F(ZoneRuntimeRules, WithoutTheFixANewBundleWaitsForFixesAndTheDwell) {
  // The same replacement without a fix (position unknown): the new zone stays unknown, as the
  // engine's rules say, so the test above can fail.
  ZoneController c(config());
  std::vector<ZoneEvent> events;
  std::string error;
  ASSERT_TRUE(
      c.on_bundle(rules_bytes(bundle(2, 1000, true)), kRulesStart, events, error).accepted());
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(c.demands(kRulesStart).outside_operating_area);
  EXPECT_FALSE(c.demands(kRulesStart + seconds(10)).speed_limit_kmh);
}

TEST_F(ZoneRuntimeRules, AFixWithinTheMarginOfANewZoneDecidesNothing) {
  ZoneController c(config());
  std::vector<ZoneEvent> events;
  std::string error;
  const auto edge = fix_at(1000 - 200 + 3, 0, kRulesStart);  // 3 m inside the new area's west edge
  ASSERT_TRUE(
      c.on_bundle(rules_bytes(bundle(1, 1000)), kRulesStart, events, error, &edge).accepted());
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(c.demands(kRulesStart).outside_operating_area);  // unknown, not outside
}

TEST_F(ZoneRuntimeRules, EveryOfferIsCountedAndTheLatestRefusalKept) {
  ZoneController c(config());
  std::vector<ZoneEvent> events;
  std::string error;
  EXPECT_EQ(c.counters().offered, 0u);
  ASSERT_TRUE(c.on_bundle(rules_bytes(bundle(2, 0)), kRulesStart, events, error).accepted());
  // The retained redelivery: neither accepted nor refused.
  EXPECT_EQ(c.on_bundle(rules_bytes(bundle(2, 0)), kRulesStart, events, error).outcome,
            BundleOutcome::kAlreadyInForce);
  EXPECT_FALSE(c.counters().last_refusal);
  const auto older =
      c.on_bundle(rules_bytes(bundle(1, 0)), kRulesStart + seconds(1), events, error);
  EXPECT_EQ(older.reason, BundleRefusal::kNotNewer);
  const auto garbage = c.on_bundle(rules_bytes("\x0a\xff\xff not a bundle"),
                                   kRulesStart + seconds(2), events, error);
  EXPECT_EQ(garbage.reason, BundleRefusal::kMalformed);
  const auto big = c.on_oversized(2 << 20, 1 << 20, kRulesStart + seconds(3));
  EXPECT_EQ(big.reason, BundleRefusal::kTooLarge);
  EXPECT_EQ(big.detail, "payload of 2097152 bytes exceeds 1048576 (refused unread)");
  EXPECT_EQ(big.in_force, 2u);

  const auto& n = c.counters();
  EXPECT_EQ(n.offered, 5u);
  EXPECT_EQ(n.accepted, 1u);
  EXPECT_EQ(n.refused, 3u);
  ASSERT_TRUE(n.last_refusal);
  EXPECT_EQ(n.last_refusal->reason, BundleRefusal::kTooLarge);
  EXPECT_EQ(n.last_refusal_at, kRulesStart + seconds(3));
  EXPECT_EQ(c.authority().in_force()->zones->version, 2u);  // what is in force stayed
}

TEST(BikeLockWatch, ARideEndingLockMadeOnTheBikeIsJudgedOncePerParking) {
  BikeLockWatch w;
  // The rider's key on the frame lock: locking (code 4), then locked (2).
  EXPECT_FALSE(w.on_lock_event("frame", 4, "local"));
  EXPECT_TRUE(w.on_lock_event("frame", 2, "local"));
  // The same parking: another ride-ending lock is not news.
  EXPECT_FALSE(w.on_lock_event("wheel", 2, "local"));
  // Unlocked and ridden, then locked again: a new parking.
  EXPECT_FALSE(w.on_lock_event("frame", 1, "local"));
  EXPECT_TRUE(w.on_lock_event("frame", 2, "local"));
}

TEST(BikeLockWatch, AVehicleLockCountsOnceWhateverTheLocks) {
  BikeLockWatch w;
  EXPECT_TRUE(w.on_lock_event("seat", 2, "vehicle_lock"));
  EXPECT_FALSE(w.on_lock_event("frame", 2, "vehicle_lock"));
  EXPECT_FALSE(w.on_lock_event("battery", 2, "vehicle_lock"));
}

TEST(BikeLockWatch, CommandsOtherLocksAndFailuresAreNotJudged) {
  BikeLockWatch w;
  // A lock command was judged before it ran (CommandService's lock guard).
  EXPECT_FALSE(w.on_lock_event("frame", 2, "command:0f3a"));
  // A seat or battery lock alone does not end a ride.
  EXPECT_FALSE(w.on_lock_event("seat", 2, "local"));
  EXPECT_FALSE(w.on_lock_event("battery", 2, "local"));
  // A failed lock (code 6) did not lock anything.
  EXPECT_FALSE(w.on_lock_event("frame", 6, "local"));
  // None of those used up the parking's report.
  EXPECT_TRUE(w.on_lock_event("frame", 2, "local"));
}

}  // namespace
}  // namespace fleetgw::geofence
