// What each simulated node puts on the bus: the message encoders (values from the bike's state
// and RidePhysics, quantised into the catalogue's raw fields) and the §3.7 fault-word timing.

#include <algorithm>
#include <string>

#include "gateway/sim/bike_impl.h"

namespace fleetgw::sim {

using namespace detail;

// ---------------------------------------------------------------------------------------------
// Messages

void Bike::Impl::send_mc_status() {
  const double temps[3] = {ride_.pcb_temp, ride_.motor_temp, ride_.mcu_temp};
  for (std::size_t i = 0; i < 3; ++i) {
    mc_temp_extremes_[2 * i] = std::max(mc_temp_extremes_[2 * i], temps[i]);
    mc_temp_extremes_[2 * i + 1] = std::min(mc_temp_extremes_[2 * i + 1], temps[i]);
  }
  const double v_kmh = ride_.speed_ms * 3.6;
  const double discharge_ma = std::max(0.0, -ride_.current_a) * 1000.0;
  // Range and consumption from this trip once it is long enough to say anything.
  int64_t range_raw = 0xFFFF;
  int64_t consumption_raw = 0xFF;
  const double remaining_wh = ride_.remaining_mah / 1000.0 * kNominalPackV;
  const double wh_per_km =
      ride_.trip_m > 500 ? std::max(2.0, ride_.trip_wh / (ride_.trip_m / 1000.0)) : 9.0;
  range_raw = clamp_raw(remaining_wh / wh_per_km, 0, 0xFFFE);
  if (ride_.trip_m >= 100)
    consumption_raw = clamp_raw(ride_.trip_mah / (ride_.trip_m / 1000.0) / 10.0, 0, 0xFE);
  send(Node::kMc,
       writer(0x710, 0x10)
           .raw("speed_kmh", clamp_raw(v_kmh * 10, 0, 0xFFFF))
           .raw("motor_rpm", clamp_raw(ride_.motor_rpm, 0, 0xFFFF))
           .raw("power_w", clamp_raw(ride_.motor_w, 0, 0xFFFF))
           .raw("voltage_v", clamp_raw(ride_.pack_v * 1000, 0, 0xFFFF))
           .raw("current_a", clamp_raw(discharge_ma, 0, 0xFFFF))
           .raw("cadence_rpm", clamp_raw(ride_.cadence, 0, 255))
           .raw("torque_nm", clamp_raw(ride_.torque, 0, 255))
           .raw("direction", v_kmh > 0.05 ? 0 : 2)
           .raw("assist", assist_)
           .boolean("headlight", headlight_)
           .raw("soc_pct", clamp_raw(ride_.remaining_mah / ride_.full_mah * 100, 0, 100))
           .raw("range_km", range_raw)
           .raw("odo_km", std::min<int64_t>(static_cast<int64_t>(ride_.odo_m / 1000), 0xFFFF))
           .raw("consumption_ah_per_km", consumption_raw)
           .raw("pcb_temp_c", temp_raw(ride_.pcb_temp))
           .raw("motor_temp_c", temp_raw(ride_.motor_temp))
           .raw("mcu_temp_c", temp_raw(ride_.mcu_temp))
           .raw("trip_km", std::min<int64_t>(static_cast<int64_t>(ride_.trip_m / 100), 0xFFFF))
           .raw("trip_time_s", std::min<int64_t>(static_cast<int64_t>(ride_.trip_riding_s), 0xFFFF))
           .frame());
}

void Bike::Impl::send_mc_odometer() {
  send(Node::kMc, writer(0x710, 0x15)
                      .raw("odo_km", static_cast<int64_t>(ride_.odo_m / 100))
                      .raw("odo_time_min", static_cast<int64_t>(ride_.odo_riding_s / 60))
                      .raw("trip_km", static_cast<int64_t>(ride_.trip_m / 100))
                      .raw("trip_time_min", static_cast<int64_t>(ride_.trip_riding_s / 60))
                      .frame());
}

void Bike::Impl::send_device_info(Node src, uint16_t can_id, uint8_t function,
                                  const DeviceStrings& d, std::string_view serial_suffix) {
  send(src, writer(can_id, function)
                .text("model", d.model)
                .text("serial", d.serial + std::string(serial_suffix))
                .text("hw", d.hw)
                .text("fw", d.fw)
                .frame());
}

void Bike::Impl::send_mc_settings() {
  send(Node::kMc, writer(0x713, 0x54)
                      .raw("wheel_size_cm", sc_.wheel_circumference_cm)
                      .raw("mode", mc_mode_)
                      .raw("speed_limit_kmh", clamp_raw(sc_.speed_limit_kmh, 0, 255))
                      .raw("wheel_adjust_cm", wheel_adjust_cm_)
                      .raw("speed_limit_offset_kmh", speed_limit_offset_)
                      .frame());
}

void Bike::Impl::send_mc_params2() {
  send(Node::kMc, writer(0x713, 0x55)
                      .raw("selector", params2_[0])
                      .raw("p1", params2_[1])
                      .raw("p2", params2_[2])
                      .raw("p3", params2_[3])
                      .raw("p4_min", params2_[4])
                      .raw("p5", 0)
                      .frame());
}

void Bike::Impl::send_mc_tuning() {
  AppFrame f = writer(0x713, 0x56).frame();
  std::copy(tuning_.begin(), tuning_.end(), f.data.data());
  send(Node::kMc, f);
}

// The MC's lifetime records, in answer to the service dongle's reads on 0x751 (spec 3.2.11,
// 3.2.12). The history before the simulation is a fixed, plausible past: 400 power-ons and 4
// minutes of operation per km of the starting ODO (15 km/h); the counters are the fault
// activations of this run.
void Bike::Impl::send_mc_lifetime(bool second) {
  if (second) {
    static constexpr std::string_view kNames[] = {
        "mcu_fault_count",         "cadence_sensor_fault_count", "throttle_sensor_fault_count",
        "mos_short_count",         "bus_voltage_fault_count",    "circuit_fault_count",
        "te_mcu_fault_count",      "te_circuit_fault_count"};
    motinova::MessageWriter w = writer(0x715, 0xAC);
    for (std::size_t i = 0; i < 8; ++i) w.raw(kNames[i], mc_fault_counts_[13 + i]);
    send(Node::kMc, w.frame());
    return;
  }
  static constexpr std::string_view kNames[] = {
      "over_current_count",        "under_voltage_count",      "over_voltage_count",
      "rotor_locked_count",        "over_heat_count",          "speed_sensor_fault_count",
      "torque_sensor_fault_count", "hall_or_brake_fault_count", "phase_line_fault_count",
      "ntc_fault_count",           "bms_check_fault_count",    "hmi_check_fault_count",
      "pbu_check_fault_count"};
  motinova::MessageWriter w = writer(0x715, 0xA2);
  w.raw("power_on_count", static_cast<int64_t>(400 + boot_gen_))
      .raw("operating_time_min", static_cast<int64_t>(sc_.odo_km * 4.0 + ride_.runtime_s / 60));
  for (std::size_t i = 0; i < 13; ++i) w.raw(kNames[i], mc_fault_counts_[i]);
  // Before the first running data the extremes are the ambient temperature.
  auto extreme = [this](std::size_t i) {
    const double t = mc_temp_extremes_[i];
    return temp_raw(t < -500 || t > 500 ? sc_.ambient_c : t);
  };
  w.raw("pcb_temp_max_c", extreme(0))
      .raw("pcb_temp_min_c", extreme(1))
      .raw("motor_temp_max_c", extreme(2))
      .raw("motor_temp_min_c", extreme(3))
      .raw("mcu_temp_max_c", extreme(4))
      .raw("mcu_temp_min_c", extreme(5));
  send(Node::kMc, w.frame());
}

void Bike::Impl::send_bms_status() {
  uint8_t flags = 0;
  int64_t charge_min = 0;
  if (ride_.current_a > 0.01 && ride_.charger_a > 0) {
    flags |= 0x01;  // charging
    charge_min = clamp_raw(
        (ride_.full_mah - ride_.remaining_mah) / (ride_.current_a * 1000.0) * 60.0, 0, 0xFFFF);
  }
  const double current_ma = ride_.current_a * 1000.0 * (opts_.bms_current_charge_positive ? 1 : -1);
  send(Node::kBms,
       writer(0x720, 0x10)
           .raw("voltage_v", clamp_raw(ride_.pack_v * 1000, 0, 0xFFFF))
           .raw("current_a", clamp_raw(current_ma, -32768, 32767))
           .raw("remaining_mah", clamp_raw(ride_.remaining_mah, 0, 0xFFFF))
           .raw("full_mah", clamp_raw(ride_.full_mah, 0, 0xFFFF))
           .raw("temp_c", temp_raw(ride_.batt_temp))
           .raw("soc_pct", clamp_raw(ride_.remaining_mah / ride_.full_mah * 100, 0, 100))
           .raw("state_flags", flags)
           .raw("soh_pct", sc_.soh_pct)
           .raw("cycles", sc_.cycles)
           .raw("charge_time_min", charge_min)
           .frame());
}

void Bike::Impl::send_bms_cells() {
  motinova::MessageWriter w = writer(0x720, 0x11);
  const double mean_mv = ride_.pack_v * 1000.0 / kSeriesCells;
  for (std::size_t i = 0; i < kSeriesCells; ++i) {
    w.element("cells_mv", i,
              static_cast<uint64_t>(clamp_raw(mean_mv + cell_spread_mv_[i], 0, 0xFFFF)));
  }
  send(Node::kBms, w.frame());  // cells 14..16 stay 0: a 13S pack
}

void Bike::Impl::send_bms_nameplate() {
  send(Node::kBms, writer(0x720, 0x14)
                       .raw("rated_capacity_mah", sc_.capacity_mah)
                       .raw("rated_voltage_v", 48)
                       .text("date_text", "24/05/03")
                       .raw("max_current_a", 20)
                       .frame());
}

void Bike::Impl::send_bms_temps() {
  // Hottest / coolest cell around the pack temperature; the two u16 values are illegible in
  // the spec (U22): the sim sends minutes since power-on and minutes of the charge session.
  send(Node::kBms, writer(0x720, 0x18)
                       .raw("temp_max_c", temp_raw(ride_.batt_temp + 1.5))
                       .raw("temp_min_c", temp_raw(ride_.batt_temp - 1.0))
                       .raw("value_1", clamp_raw(ride_.runtime_s / 60, 0, 0xFFFF))
                       .raw("time_2", clamp_raw(ride_.charge_session_s / 60, 0, 0xFFFF))
                       .frame());
}

void Bike::Impl::send_pack_stats() {
  send(Node::kBms,
       writer(0x725, 0x50)
           .raw("max_temp_c", temp_raw(ride_.max_temp))
           .raw("min_temp_c", temp_raw(ride_.min_temp))
           .raw("max_discharge_current_a", clamp_raw(ride_.max_discharge_ma, 0, 0xFFFF))
           .raw("max_charge_current_a", clamp_raw(ride_.max_charge_ma, 0, 0xFFFF))
           .raw("cycles", sc_.cycles)
           .raw("charge_time_total_h", clamp_raw(ride_.charge_total_s / 3600, 0, 0xFFFF))
           .raw("charge_time_longest_h", clamp_raw(ride_.charge_longest_s / 3600, 0, 0xFFFF))
           .raw("runtime_min", clamp_raw(ride_.runtime_s / 60, 0, 0xFFFFFFFF))
           .raw("soh_pct", sc_.soh_pct)
           .frame());
}

void Bike::Impl::send_lock_status(std::size_t i) {
  const LockSim& l = locks_[i];
  const uint16_t id = broadcast_id(l.node);
  // Bolt bit 0 = 1 while the bolt is thrown (locked); the polarity is U20.
  const bool bolt = l.state == LockState::kLocked || l.state == LockState::kUnlockFailed ||
                    l.state == LockState::kUnlocking;
  motinova::MessageWriter w = writer(id, 0x10);
  w.raw("voltage_v", clamp_raw(l.voltage_mv - (l.moving ? 250 : 0), 0, 0xFFFF))
      .raw("current_a", l.moving ? 620 : 12)
      .raw("temp_c", temp_raw(sc_.ambient_c + (l.moving ? 4 : 2)))
      .raw("state", static_cast<int64_t>(l.state))
      .raw("bolts", bolt ? 1 : 0);
  if (l.node == Node::kLock4) w.raw("motor_rpm", l.moving ? 2400 : 0);
  send(l.node, w.frame());
}

uint32_t& Bike::Impl::fault_word(Node n) {
  switch (n) {
    case Node::kMc:
      return mc_faults_;
    case Node::kBms:
      return bms_faults_;
    case Node::kObc:
      return obc_faults_;
    default:
      return locks_.at(static_cast<std::size_t>(motinova::lock_index(n))).faults;
  }
}

Bike::Impl::FaultTx& Bike::Impl::fault_tx(Node n) {
  switch (n) {
    case Node::kMc:
      return mc_fault_tx_;
    case Node::kBms:
      return bms_fault_tx_;
    case Node::kObc:
      return obc_fault_tx_;
    default:
      return locks_.at(static_cast<std::size_t>(motinova::lock_index(n))).fault_tx;
  }
}

void Bike::Impl::send_fault_word(Node n) {
  uint16_t id = broadcast_id(n);
  uint8_t function = 0x11;  // MC and locks
  if (n == Node::kBms) function = 0x12;
  if (n == Node::kObc) function = 0x15;
  const uint32_t word = fault_word(n);
  FaultTx& tx = fault_tx(n);
  tx.last_sent = word;
  tx.last_time = now_;
  send(n, writer(id, function).raw("raw", word).frame());
}

// §3.7 (U12): every 200 ms while a fault is present, every 1 s when all is well, and at once on
// a change (set_faults).
void Bike::Impl::fault_tick(Node n) {
  const FaultTx& tx = fault_tx(n);
  if (fault_word(n) != 0 || now_ - tx.last_time >= ms(990)) send_fault_word(n);
}

void Bike::Impl::set_faults(Node n, uint32_t bits, bool on) {
  uint32_t& word = fault_word(n);
  const uint32_t before = word;
  word = on ? (word | bits) : (word & ~bits);
  if (n == Node::kMc) {
    // Counted in the MC's lifetime records (bits 0..20 of the normalised word).
    const uint32_t rising = word & ~before;
    for (std::size_t b = 0; b < mc_fault_counts_.size(); ++b) {
      if ((rising >> b) & 1U) ++mc_fault_counts_[b];
    }
  }
  if (word != before) after(ms(2), [this, n] { send_fault_word(n); });
}

}  // namespace fleetgw::sim
