#include "gateway/sim/ride_physics.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fleetgw::sim {
namespace {

// Open-circuit voltage of one cell at SOC 0, 10, ... 100 %.
constexpr double kCellOcv[] = {3.00, 3.45, 3.55, 3.62, 3.68, 3.74, 3.81, 3.89, 3.97, 4.07, 4.20};

}  // namespace

double cell_ocv(double soc_pct) {
  const double x = std::clamp(soc_pct, 0.0, 100.0) / 10.0;
  const int i = std::min(9, static_cast<int>(x));
  return kCellOcv[i] + (kCellOcv[i + 1] - kCellOcv[i]) * (x - i);
}

double assist_ratio(uint8_t assist) {
  switch (assist) {
    case 0x01:
      return 0.5;
    case 0x02:
      return 1.0;
    case 0x03:
      return 1.7;
    case 0x04:
      return 2.6;
    case 0x22:
      return 1.2;
    case 0x33:
      return 1.4;
    default:
      return 0.0;  // off; walk is handled separately
  }
}

void RidePhysics::step(const RideInputs& in) {
  const double dt = kPhysicsStepS;
  const double grade_pct = in.grade_pct;
  double target_kmh = in.profile_kmh;
  if (!in.powered || charger_a > 0) target_kmh = 0;  // nobody rides a dead or charging bike
  // Riders in the sim never pedal past the assist cut-off (walk assist: 6 km/h).
  target_kmh = std::min(target_kmh, in.assist == kWalkAssist ? 6.0 : in.limit_kmh);

  // A little seeded wobble around the target speed (Ornstein-Uhlenbeck, sigma ~0.5 km/h).
  wobble_kmh += -wobble_kmh * dt / 5.0 + 0.35 * in.noise * std::sqrt(dt);
  const double desired_ms =
      target_kmh > 0 ? std::max(0.0, std::min(target_kmh + wobble_kmh, in.limit_kmh)) / 3.6 : 0.0;
  const double v0 = speed_ms;
  double v1 = v0 + std::clamp(desired_ms - v0, -kMaxBrake * dt, kMaxAccel * dt);
  if (v1 < 0.05) v1 = desired_ms > 0 ? v1 : 0.0;
  speed_ms = v1;

  const double v_avg = (v0 + v1) / 2;
  const double dist = v_avg * dt;
  odo_m += dist;
  trip_m += dist;
  if (v_avg > 0) {
    odo_riding_s += dt;
    trip_riding_s += dt;
  }

  // Power at the wheel, split between rider and motor by the assist ratio.
  const double slope = grade_pct / 100.0;
  const double force = kMassKg * kGravity * (kCrr + slope) +
                       0.5 * kAirDensity * kCdA * v_avg * v_avg + kMassKg * (v1 - v0) / dt;
  const double wheel_w = std::max(0.0, force * v_avg);
  double assist_w = 0;
  if (in.assist_allowed && v_avg > 0) {
    if (in.assist == kWalkAssist) {
      assist_w = v_avg * 3.6 <= 6.0 ? std::min(wheel_w, 150.0) : 0.0;
    } else if (v_avg * 3.6 <= in.limit_kmh) {
      const double r = assist_ratio(in.assist);
      assist_w = std::min(kMotorMaxW, wheel_w * r / (1 + r));
    }
  }
  motor_w = assist_w;
  const double rider_w = wheel_w - assist_w;
  cadence = v_avg > 0.3 ? std::clamp(50 + v_avg * 3.6 * 1.2, 45.0, 95.0) : 0.0;
  torque = cadence > 0 ? rider_w / (cadence * 2 * std::numbers::pi / 60.0) : 0.0;
  motor_rpm = assist_w > 0 ? cadence * 36.0 : 0.0;  // mid-drive reduction ~1:36

  // Pack: electrical load -> discharge current with IR drop; charger -> CC/CV charge current.
  const double soc = remaining_mah / full_mah * 100.0;
  const double ocv = cell_ocv(soc) * kSeriesCells;
  double load_w = 0;
  if (in.powered)
    load_w = assist_w / kMotorEfficiency + kStandbyW + (in.headlight ? kHeadlightW : 0);
  double i_dis = 0;
  const double disc = ocv * ocv - 4 * kPackResistance * load_w;
  if (load_w > 0) {
    i_dis = disc > 0 ? (ocv - std::sqrt(disc)) / (2 * kPackResistance) : load_w / ocv;
  }
  double i_chg = 0;
  if (charger_a > 0 && soc < 99.95 && !in.bms_protection_tripped) {
    const double cell = cell_ocv(soc);
    i_chg = cell < 4.12 ? charger_a : charger_a * std::clamp((4.2 - cell) / 0.08, 0.05, 1.0);
  }
  current_a = i_chg - i_dis;
  pack_v = ocv + current_a * kPackResistance;
  const double dmah = current_a * 1000.0 * dt / 3600.0;
  remaining_mah = std::clamp(remaining_mah + dmah, 0.0, full_mah);
  energy_out_wh += pack_v * i_dis * dt / 3600.0;
  energy_in_wh += pack_v * i_chg * dt / 3600.0;
  trip_mah += i_dis * 1000.0 * dt / 3600.0;
  trip_wh += pack_v * i_dis * dt / 3600.0;
  if (i_chg > 0) {
    charge_session_s += dt;
    charge_total_s += dt;
  }
  if (in.powered) runtime_s += dt;

  // Temperatures: first-order towards ambient, driven by I²R in the pack and motor losses.
  const double amb = in.ambient_c;
  batt_temp += dt * ((current_a * current_a * 0.4) / 300.0 - (batt_temp - amb) / 1800.0);
  motor_temp += dt * ((assist_w * 0.25) / 900.0 - (motor_temp - amb) / 600.0);
  pcb_temp += dt * ((amb + 3 + i_dis * 1.5) - pcb_temp) / 300.0;
  mcu_temp += dt * ((pcb_temp + 2) - mcu_temp) / 120.0;
  max_temp = std::max(max_temp, batt_temp);
  min_temp = std::min(min_temp, batt_temp);
  max_discharge_ma = std::max(max_discharge_ma, i_dis * 1000.0);
  max_charge_ma = std::max(max_charge_ma, i_chg * 1000.0);
}

}  // namespace fleetgw::sim
