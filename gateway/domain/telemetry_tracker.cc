#include "gateway/domain/telemetry_tracker.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "motinova/can.h"

namespace fleetgw::domain {

TelemetryTracker::TelemetryTracker(TelemetryConfig config, std::array<std::string, 5> lock_kinds,
                                   DomainSink& sink)
    : config_(std::move(config)), lock_kinds_(std::move(lock_kinds)), sink_(sink) {}

void TelemetryTracker::set_riding(bool riding, Micros now) {
  if (riding == riding_) return;
  riding_ = riding;
  // Entering a ride samples at once; leaving it, the next sample comes after the parked interval.
  next_due_ = riding ? now : now + config_.parked_interval;
}

void TelemetryTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return;
  const std::string_view name = msg.desc->name;
  const motinova::Node src = msg.desc->source();
  Discrete next = discrete_;
  if (name == "mc_status") {
    update(speed_, msg, "speed_kmh", now);
    update(rpm_, msg, "motor_rpm", now);
    update(power_, msg, "power_w", now);
    update(mc_v_, msg, "voltage_v", now);
    update(mc_i_, msg, "current_a", now);
    update(cadence_, msg, "cadence_rpm", now);
    update(torque_, msg, "torque_nm", now);
    update(assist_, msg, "assist", now);
    update(mc_soc_, msg, "soc_pct", now);
    update(range_, msg, "range_km", now);
    update(odo_, msg, "odo_km", now);
    update(trip_, msg, "trip_km", now);
    update(pcb_, msg, "pcb_temp_c", now);
    update(motor_t_, msg, "motor_temp_c", now);
    update(mcu_, msg, "mcu_temp_c", now);
    if (const auto a = msg.raw("assist")) next.assist = static_cast<int>(*a);
  } else if (name == "mc_odometer") {
    update(fine_odo_, msg, "odo_km", now);
    update(fine_trip_, msg, "trip_km", now);
  } else if (name == "bms_status") {
    update(bms_v_, msg, "voltage_v", now);
    update(bms_i_, msg, "current_a", now);
    update(bms_soc_, msg, "soc_pct", now);
    update(remaining_, msg, "remaining_mah", now);
    update(full_, msg, "full_mah", now);
    update(pack_t_, msg, "temp_c", now);
    if (const auto c = msg.number("charging")) next.charging = *c != 0;
  } else if (name == "lock_status" && motinova::is_lock(src)) {
    const auto i = static_cast<std::size_t>(motinova::lock_index(src));
    update(lock_state_[i], msg, "state", now);
    if (const auto s = msg.raw("state")) next.locks[i] = static_cast<int>(*s);
  } else {
    return;
  }
  if (!heard_) {
    heard_ = true;
    if (!next_due_) next_due_ = now;
  }
  // A discrete change is sampled right away; the first value of each is a baseline, not a change.
  const bool changed = (discrete_.assist && next.assist != discrete_.assist) ||
                       (discrete_.charging && next.charging != discrete_.charging) || [&] {
                         for (std::size_t i = 0; i < next.locks.size(); ++i) {
                           if (discrete_.locks[i] && next.locks[i] != discrete_.locks[i]) {
                             return true;
                           }
                         }
                         return false;
                       }();
  discrete_ = next;
  if (changed) sample(now);
}

void TelemetryTracker::tick(Micros now) {
  if (!next_due_ || now < *next_due_) return;
  sample(now);
  // Catch up without bursts: the next sample is one interval after this one.
  next_due_ = std::max(*next_due_ + interval(), now + interval() / 2);
}

void TelemetryTracker::sample(Micros now) {
  if (!heard_) return;
  const Micros age = config_.stale;
  TelemetryReading r;
  r.ts_us = now.count();
  r.speed_kmh = fresh(speed_, now, age);
  r.motor_rpm = fresh(rpm_, now, age);
  r.power_w = fresh(power_, now, age);
  r.cadence_rpm = fresh(cadence_, now, age);
  r.torque_nm = fresh(torque_, now, age);
  if (const auto a = fresh(assist_, now, age)) r.assist = static_cast<int>(*a);
  r.range_km = fresh(range_, now, age);
  r.odo_km = fresh(fine_odo_, now, age);
  if (!r.odo_km) r.odo_km = fresh(odo_, now, age);
  r.trip_km = fresh(fine_trip_, now, age);
  if (!r.trip_km) r.trip_km = fresh(trip_, now, age);
  r.pcb_temp_c = fresh(pcb_, now, age);
  r.motor_temp_c = fresh(motor_t_, now, age);
  r.mcu_temp_c = fresh(mcu_, now, age);
  r.voltage_v = fresh(mc_v_, now, age);
  r.current_a = fresh(mc_i_, now, age);
  if (!r.voltage_v || !r.current_a) {
    r.voltage_v = fresh(bms_v_, now, age);
    const auto i = fresh(bms_i_, now, age);
    r.current_a = i ? std::optional<double>(-*i) : std::nullopt;
  }
  r.soc_pct = fresh(bms_soc_, now, age);
  if (!r.soc_pct) r.soc_pct = fresh(mc_soc_, now, age);
  r.remaining_mah = fresh(remaining_, now, age);
  r.full_mah = fresh(full_, now, age);
  r.pack_temp_c = fresh(pack_t_, now, age);
  if (discrete_.charging && fresh(bms_v_, now, age)) r.charging = discrete_.charging;
  auto lock_of = [&](const std::vector<std::string>& kinds) -> std::optional<int> {
    for (std::size_t i = 0; i < lock_kinds_.size(); ++i) {
      if (std::find(kinds.begin(), kinds.end(), lock_kinds_[i]) == kinds.end()) continue;
      if (const auto s = fresh(lock_state_[i], now, age)) return static_cast<int>(*s);
    }
    return std::nullopt;
  };
  r.wheel_lock_state = lock_of(config_.wheel_lock_kinds);
  r.battery_lock_state = lock_of(config_.battery_lock_kinds);
  r.position = position_;
  storage::Bytes payload = telemetry_payload(r);
  sink_.batch().telemetry.push_back({r.record(), std::move(payload)});
  ++samples_;
}

}  // namespace fleetgw::domain
