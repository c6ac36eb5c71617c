// Helpers shared by the storage tests: a self-deleting temporary directory, builders for
// plausible records, the store's row counts and a file's bytes. Contract: every test works on real
// SQLite files under its own TempDir.
#pragma once

#include "tests/support/temp_dir.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>

#include "storage/store.h"

namespace fleetgw::storage::testing {

// The suites' one temporary directory (tests/support).
using TempDir = ::fleetgw::testing::TempDir;

// The row count of every table, by name, as the store reports it.
inline std::map<std::string, std::uint64_t> counts(Store& store) {
  std::map<std::string, std::uint64_t> out;
  for (const auto& [table, rows] : store.stats().table_rows) out[table] = rows;
  return out;
}

// The whole file at `path`, bytes as they are ("" if it cannot be read).
inline std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

inline Bytes payload_of(const std::string& text) {
  return Bytes(text.begin(), text.end());
}

inline TelemetryRow telemetry_at(std::int64_t ts_us) {
  TelemetryRow t;
  t.ts_us = ts_us;
  t.speed_kmh = 21.5;
  t.assist_level = 3;
  t.soc_pct = 77.0;
  t.voltage_v = 41.2;
  t.current_a = 6.3;
  t.motor_temp_c = 45.0;
  t.controller_temp_c = 38.5;
  t.battery_temp_c = 24.0;
  t.wheel_lock_state = 0;
  t.battery_lock_state = 1;
  return t;
}

inline FaultEventRow fault_at(std::int64_t ts_us, int code) {
  FaultEventRow f;
  f.node = 1;
  f.bit = code % 32;
  f.code = code;
  f.name = "motor_overtemp";
  f.severity = "warning";
  f.event = FaultEventKind::kRaised;
  f.first_seen_us = ts_us;
  f.last_seen_us = ts_us;
  f.occurrences = 1;
  return f;
}

inline RideRow ride_named(const std::string& id, std::int64_t start_us, bool closed) {
  RideRow r;
  r.ride_id = id;
  r.start_us = start_us;
  r.state = closed ? RideState::kClosed : RideState::kOpen;
  if (closed) r.end_us = start_us + 600'000'000;
  r.duration_s = 600;
  r.moving_s = 540;
  r.start_odo_km = 1234.5;
  r.end_odo_km = 1237.25;
  r.distance_km = 2.75;
  r.distance_integrated_km = 2.71;
  r.max_speed_kmh = 25.1;
  r.avg_speed_kmh = 18.3;
  r.energy_wh = 31.5;
  r.energy_mah = 870;
  r.soc_start_pct = 80;
  r.soc_end_pct = 74;
  r.assist_time_s = {{"eco", 200.0}, {"tour", 340.0}};
  r.fault_count = 1;
  return r;
}

inline PackSnapshotRow pack_at(std::int64_t ts_us) {
  PackSnapshotRow p;
  p.ts_us = ts_us;
  p.voltage_v = 40.8;
  p.current_a = -1.2;
  p.soc_pct = 66;
  p.soh_pct = 97;
  p.cycles = 142;
  p.temps_c = {23.0, 24.5, 25.0};
  p.cell_min_mv = 3650;
  p.cell_max_mv = 3682;
  p.cell_spread_mv = 32;
  p.cell_min_index = 4;
  p.cell_max_index = 9;
  p.lifetime_json = R"({"charge_ah":1234.5,"discharge_ah":1201.0})";
  return p;
}

inline LockEventRow lock_at(std::int64_t ts_us) {
  return LockEventRow{0, ts_us, 7, "wheel", "unlocked", "locked", "command:c-1"};
}

inline CommandResultRow command_result(const std::string& id, std::int64_t ts_us) {
  return CommandResultRow{0, id, ts_us, "ok", "", "locked", 850};
}

}  // namespace fleetgw::storage::testing
