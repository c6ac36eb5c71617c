// RidePhysics, the bike's physical model on its own: what the rider and the pack do for given
// inputs, independent of CAN and scheduling.
#include <gtest/gtest.h>

#include "gateway/sim/ride_physics.h"

namespace fleetgw::sim {
namespace {

RidePhysics fresh_pack(double soc_pct) {
  RidePhysics p;
  p.full_mah = 14'000;
  p.remaining_mah = p.full_mah * soc_pct / 100.0;
  p.pack_v = cell_ocv(soc_pct) * kSeriesCells;
  return p;
}

RideInputs riding(double kmh, uint8_t assist) {
  RideInputs in;
  in.profile_kmh = kmh;
  in.limit_kmh = 25;
  in.assist = assist;
  in.assist_allowed = true;
  in.powered = true;
  return in;
}

TEST(RidePhysics, AssistedRideDrawsThePackAndCoversDistance) {
  RidePhysics p = fresh_pack(80);
  const double start_mah = p.remaining_mah;
  for (int i = 0; i < 600; ++i) p.step(riding(20, 2));  // one minute
  EXPECT_NEAR(p.speed_ms * 3.6, 20, 1.0);
  EXPECT_GT(p.odo_m, 250);  // the first seconds accelerate
  EXPECT_LT(p.odo_m, 340);
  EXPECT_GT(p.motor_w, 0);
  EXPECT_LT(p.current_a, 0) << "discharge is negative";
  EXPECT_LT(p.remaining_mah, start_mah);
  EXPECT_GT(p.energy_out_wh, 0);
}

TEST(RidePhysics, NeverFasterThanTheLimitAndWalkAssistStopsAtSix) {
  RidePhysics p = fresh_pack(80);
  for (int i = 0; i < 1200; ++i) p.step(riding(40, 3));
  EXPECT_LE(p.speed_ms * 3.6, 25.0 + 1e-9);
  RidePhysics w = fresh_pack(80);
  for (int i = 0; i < 600; ++i) w.step(riding(20, kWalkAssist));
  EXPECT_LE(w.speed_ms * 3.6, 6.0 + 1e-9);
}

TEST(RidePhysics, ParkedOnTheChargerChargesAndDoesNotMove) {
  RidePhysics p = fresh_pack(30);
  p.charger_a = 4;
  const double start_mah = p.remaining_mah;
  for (int i = 0; i < 36'000; ++i) p.step(riding(20, 2));  // one hour: nobody rides a charging bike
  EXPECT_EQ(p.odo_m, 0);
  EXPECT_NEAR(p.remaining_mah - start_mah, 4'000, 300) << "4 A for an hour, minus standby";
  EXPECT_GT(p.energy_in_wh, 0);
  RidePhysics tripped = fresh_pack(30);
  tripped.charger_a = 4;
  RideInputs in = riding(0, 2);
  in.bms_protection_tripped = true;
  for (int i = 0; i < 600; ++i) tripped.step(in);
  EXPECT_LT(tripped.remaining_mah, fresh_pack(30).remaining_mah) << "protection stops charging";
}

}  // namespace
}  // namespace fleetgw::sim
