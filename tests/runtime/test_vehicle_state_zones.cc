// The retained last-known state: it lists the geofence's outside_operating_area alarm (not an
// AlarmTracker alarm) among its active alarms while it is raised, after the tracker's own; and a
// new GNSS fix counts as a change only once the bike moved (StatePositionFilter).
#include <gtest/gtest.h>

#include "fleetgw/v1/state.pb.h"
#include "gateway/runtime/vehicle_state.h"

namespace fleetgw::runtime {
namespace {

v1::VehicleState decoded(const VehicleStateInputs& in) {
  v1::VehicleState s;
  EXPECT_TRUE(s.ParseFromString(build_vehicle_state(in)));
  return s;
}

TEST(VehicleStateZones, TheOperatingAreaAlarmIsListedWhileRaised) {
  VehicleStateInputs in;
  in.active_alarms = {"unauthorised_movement"};
  EXPECT_EQ(decoded(in).active_alarms_size(), 1);
  in.outside_operating_area = true;
  const auto raised = decoded(in);
  ASSERT_EQ(raised.active_alarms_size(), 2);
  EXPECT_EQ(raised.active_alarms(0), v1::ALARM_KIND_UNAUTHORISED_MOVEMENT);
  EXPECT_EQ(raised.active_alarms(1), v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  // A change the throttle sees: the comparable forms differ.
  VehicleStateInputs cleared = in;
  cleared.outside_operating_area = false;
  EXPECT_NE(build_vehicle_state(in, false), build_vehicle_state(cleared, false));
}

gnss::Fix fix_at(double lat, double lon, std::int64_t fixed_at_us) {
  gnss::Fix p;
  p.lat_deg = lat;
  p.lon_deg = lon;
  p.satellites = 7;
  p.fixed_at = motinova::Micros(fixed_at_us);
  return p;
}

// A parked bike's fix changes every second (time, jitter, satellites): the state the throttle
// compares stays the same until the bike moved 20 m or the position became unknown.
TEST(VehicleStatePosition, JitterOfAParkedBikeIsNoChangeButMovingOrLosingTheFixIs) {
  StatePositionFilter filter(20);
  VehicleStateInputs in;
  auto comparable = [&](const std::optional<gnss::Fix>& p) {
    in.position = filter.comparable(p);
    return build_vehicle_state(in, false);
  };
  const auto first = fix_at(46.0512, 14.5061, 1'000'000);
  const std::string published = comparable(first);
  filter.handed_over(in.position);
  // 3 m away, a second later, one satellite more: the same state.
  auto jitter = fix_at(46.05122, 14.50613, 2'000'000);
  jitter.satellites = 8;
  EXPECT_EQ(comparable(jitter), published);
  // 45 m north: a change, and it carries the new fix.
  const auto moved = fix_at(46.0516, 14.5061, 3'000'000);
  const std::string after_move = comparable(moved);
  EXPECT_NE(after_move, published);
  v1::VehicleState s;
  ASSERT_TRUE(s.ParseFromString(after_move));
  EXPECT_EQ(s.position().lat_e7(), 460516000);
  filter.handed_over(in.position);
  // Unknown is a change too (a stale position is never kept as current).
  EXPECT_NE(comparable(std::nullopt), after_move);
  // With 0 every fix is compared as it is.
  StatePositionFilter every(0);
  in.position = every.comparable(first);
  const std::string a = build_vehicle_state(in, false);
  every.handed_over(in.position);
  in.position = every.comparable(jitter);
  EXPECT_NE(build_vehicle_state(in, false), a);
}

}  // namespace
}  // namespace fleetgw::runtime
