// Configuration of the operator alarms ([alarms] in fleetgw.toml; docs/data-model.md).
//
// Contract: a value type; validate() throws std::invalid_argument naming the offending key
// ("alarms.movement_debounce_ms: ...") when a value makes no sense.
#pragma once

#include <array>
#include <chrono>
#include <string>
#include <vector>

#include "motinova/can.h"
#include "motinova/options.h"

namespace fleetgw::domain {

struct AlarmConfig {
  using Micros = motinova::Micros;
  bool enabled = true;  // alarms.enabled
  // Evidence of movement: the MC's wheel speed above this (alarms.movement_speed_kmh)...
  double movement_speed_kmh = 1.0;
  // ...or its motor turning faster than this (alarms.movement_rpm).
  double movement_rpm = 20.0;
  // Evidence must last this long (first to last sample) before the alarm is raised: a wheel
  // nudged while parking is not a theft (alarms.movement_debounce_ms).
  Micros movement_debounce = std::chrono::seconds(2);
  // The episode ends after this long without evidence (alarms.movement_clear_s).
  Micros movement_clear = std::chrono::seconds(30);
  // SOC thresholds, percent, raised once each on the way down (alarms.low_battery_pct).
  std::vector<int> low_battery_pct{20, 10, 5};
  // A threshold re-arms (and its alarm clears) once SOC is back at threshold + this.
  double low_battery_hysteresis_pct = 3.0;
  // BMS silent this long while parked: battery removed (alarms.battery_silent_ms).
  Micros battery_silent = std::chrono::seconds(10);
  // A lock change within this window after a gateway command or 0x760 LOCK/UNLOCK is not forced
  // (copied from LockConfig::cause_window).
  Micros command_window = std::chrono::seconds(10);
  // Locks whose "locked" state makes movement unauthorised (telemetry.wheel_lock_kinds).
  std::vector<std::string> frame_lock_kinds{"frame", "wheel", "rear_wheel"};
  // U21 lock kinds by lock index (DecodeOptions::lock_kinds).
  std::array<std::string, 5> lock_kinds = motinova::DecodeOptions{}.lock_kinds;

  void validate() const;
};

}  // namespace fleetgw::domain
