// Test fixture for the `fleetgw db` CLI tests: rows as a real ride leaves them, written through
// the real Store by the tests themselves.
//
// Contract: closed_ride() is a closed 28-minute ride (25 moving) of `km` kilometres starting at
// `start_us`, with odometer readings (so its distance is the odometer's), speeds, energy and
// SOC filled in; a test changes what it needs on the returned value.
#pragma once

#include <cstdint>
#include <string>

#include "storage/store.h"

namespace fleetgw::testing {

inline storage::RideRow closed_ride(const std::string& id, std::int64_t start_us, double km) {
  constexpr std::int64_t kMinuteUs = 60'000'000;
  storage::RideRow r;
  r.ride_id = id;
  r.state = storage::RideState::kClosed;
  r.start_us = start_us;
  r.end_us = start_us + 28 * kMinuteUs;
  r.duration_s = 28 * 60;
  r.moving_s = 25 * 60;
  r.start_odo_km = 100;
  r.end_odo_km = 100 + km;
  r.distance_km = km;
  r.max_speed_kmh = 25.3;
  r.avg_speed_kmh = 17.4;
  r.energy_wh = 92.5;
  r.soc_start_pct = 90;
  r.soc_end_pct = 81;
  r.fault_count = 1;
  return r;
}

}  // namespace fleetgw::testing
