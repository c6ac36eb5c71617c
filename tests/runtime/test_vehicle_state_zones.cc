// The retained last-known state lists the geofence's outside_operating_area alarm (not an
// AlarmTracker alarm) among its active alarms while it is raised, after the tracker's own.
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

}  // namespace
}  // namespace fleetgw::runtime
