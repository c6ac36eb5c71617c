// GnssState: a position is reported only while it is current, the fault bit is its absence.
#include "gateway/gnss/gnss_state.h"

#include <gtest/gtest.h>

namespace fleetgw::gnss {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

Fix fix_at(Micros received, double lat = 52.52, double lon = 13.405) {
  Fix p;
  p.lat_deg = lat;
  p.lon_deg = lon;
  p.received_at = received;
  return p;
}

const Micros t0 = seconds(1'790'000'000);

TEST(GnssState, UnknownAndFaultyBeforeTheFirstFix) {
  GnssState s;
  EXPECT_FALSE(s.current(t0));
  EXPECT_TRUE(s.fault(t0));
  EXPECT_EQ(s.reason(t0), "gpsd not connected");
  s.on_source_connected(t0);
  EXPECT_TRUE(s.fault(t0));  // connected says nothing about a fix
  EXPECT_EQ(s.reason(t0), "no fix");
}

TEST(GnssState, AFixIsCurrentUntilItIsOlderThanMaxAge) {
  GnssState s(GnssOptions{.max_age = seconds(3)});
  s.on_source_connected(t0);
  s.on_fix(fix_at(t0));
  ASSERT_TRUE(s.current(t0 + seconds(3)));
  EXPECT_FALSE(s.fault(t0 + seconds(3)));
  EXPECT_DOUBLE_EQ(s.current(t0)->lat_deg, 52.52);
  // The owner is told when to look again, and then it is gone.
  ASSERT_TRUE(s.next_change(t0));
  const Micros stale = *s.next_change(t0);
  EXPECT_GT(stale, t0 + seconds(3));
  EXPECT_FALSE(s.current(stale));
  EXPECT_TRUE(s.fault(stale));
  EXPECT_EQ(s.reason(stale), "fix stale");
  EXPECT_FALSE(s.next_change(stale));
  // The last fix is still known as such, for "last seen at".
  ASSERT_TRUE(s.last_fix());
  EXPECT_EQ(s.last_fix()->received_at, t0);
}

TEST(GnssState, NoFixOrGpsdGoneMakesThePositionUnknownAtOnce) {
  GnssState s;
  s.on_source_connected(t0);
  s.on_fix(fix_at(t0));
  s.on_no_fix(t0 + milliseconds(100));
  EXPECT_FALSE(s.current(t0 + milliseconds(100)));
  EXPECT_EQ(s.reason(t0 + milliseconds(100)), "no fix");

  s.on_fix(fix_at(t0 + seconds(1)));
  ASSERT_TRUE(s.current(t0 + seconds(1)));
  s.on_source_lost(t0 + seconds(1));
  EXPECT_FALSE(s.current(t0 + seconds(1)));
  EXPECT_EQ(s.reason(t0 + seconds(1)), "gpsd unreachable");
  // Reconnected: still unknown until the receiver reports a fix again.
  s.on_source_connected(t0 + seconds(2));
  EXPECT_FALSE(s.current(t0 + seconds(2)));
  s.on_fix(fix_at(t0 + seconds(2)));
  EXPECT_TRUE(s.current(t0 + seconds(2)));
  EXPECT_EQ(s.fixes(), 3u);
}

TEST(GnssDistance, MatchesKnownDistances) {
  // One minute of latitude is one nautical mile (1852 m) within the sphere's 0.5 %.
  EXPECT_NEAR(distance_m(52.0, 13.0, 52.0 + 1.0 / 60, 13.0), 1852.0, 10.0);
  // Berlin -> Paris, about 878 km.
  EXPECT_NEAR(distance_m(52.5200, 13.4050, 48.8566, 2.3522), 878'000.0, 5'000.0);
  EXPECT_DOUBLE_EQ(distance_m(1.0, 2.0, 1.0, 2.0), 0.0);
}

}  // namespace
}  // namespace fleetgw::gnss
