// The physical model of the simulated bike: rider, motor, pack and temperatures, stepped at a
// fixed rate. Knows nothing about CAN, nodes or scheduling; the Bike reads these values when its
// nodes build their messages (docs/simulator.md, "Physics").
//
// Contract:
//  * Pure arithmetic on plain values: the same inputs (noise sample included) give the same
//    state on every platform and standard library. No clock, no randomness of its own: the
//    caller draws the one N(0,1) sample per step from the scenario's seeded generator.
//  * step() advances by kPhysicsStepS; quantities are SI unless the name says otherwise.
#pragma once

#include <array>
#include <cstdint>

namespace fleetgw::sim {

// Physical constants of the model.
inline constexpr double kMassKg = 100;  // bike 25 kg + rider 75 kg
inline constexpr double kGravity = 9.81;
inline constexpr double kCrr = 0.008;  // rolling resistance
inline constexpr double kCdA = 0.55;   // drag area, upright city position
inline constexpr double kAirDensity = 1.2;
inline constexpr double kMaxAccel = 1.0;   // m/s², gentle city acceleration
inline constexpr double kMaxBrake = 2.0;   // m/s²
inline constexpr double kMotorMaxW = 500;  // peak mechanical assist
inline constexpr double kMotorEfficiency = 0.8;
inline constexpr double kStandbyW = 5;  // MC + OBC + locks electronics while powered
inline constexpr double kHeadlightW = 3;
inline constexpr double kPackResistance = 0.12;  // ohm, 13S pack incl. wiring (IR drop)
inline constexpr int kSeriesCells = 13;
inline constexpr double kNominalPackV = 3.6 * kSeriesCells;
inline constexpr double kPhysicsStepS = 0.1;
// The walk-assist level (enum §3.0): the motor pushes up to 6 km/h without pedalling.
inline constexpr uint8_t kWalkAssist = 0x05;

// Open-circuit voltage of one Li-ion cell at `soc_pct` (13S spans 39.0 .. 54.6 V).
double cell_ocv(double soc_pct);
// Motor power / rider power per assist level (enum §3.0); 0 for off and unknown levels.
double assist_ratio(uint8_t assist);

// What the rest of the bike decides for one step.
struct RideInputs {
  double profile_kmh = 0;  // the scenario's target speed now (0 when parked)
  double grade_pct = 0;
  double limit_kmh = 0;  // effective assist cut-off (speed limit plus offset)
  uint8_t assist = 0;
  bool assist_allowed = false;  // MC alive, not locked, no critical fault, BMS output on
  bool powered = false;
  bool headlight = false;
  bool bms_protection_tripped = false;  // a BMS protection fault stops charging
  double ambient_c = 20;
  double noise = 0;  // one N(0,1) sample for the speed wobble
};

// State of rider, drive train and pack; public because the nodes report it field by field.
struct RidePhysics {
  void step(const RideInputs& in);

  // ride
  double speed_ms = 0;
  double wobble_kmh = 0;
  double odo_m = 0;
  double trip_m = 0;
  double odo_riding_s = 0;
  double trip_riding_s = 0;
  double trip_mah = 0;
  double trip_wh = 0;
  double cadence = 0;
  double torque = 0;
  double motor_w = 0;
  double motor_rpm = 0;
  double motor_temp = 20;
  double pcb_temp = 20;
  double mcu_temp = 20;
  // pack
  double full_mah = 14'000;
  double remaining_mah = 0;
  double pack_v = 50;
  double current_a = 0;  // charge +
  double batt_temp = 20;
  double energy_out_wh = 0;
  double energy_in_wh = 0;
  double charger_a = 0;  // charger current offered (0 = unplugged)
  double charge_session_s = 0;
  double charge_total_s = 0;
  double charge_longest_s = 0;
  double runtime_s = 0;
  double max_temp = 20;
  double min_temp = 20;
  double max_discharge_ma = 0;
  double max_charge_ma = 0;
};

}  // namespace fleetgw::sim
