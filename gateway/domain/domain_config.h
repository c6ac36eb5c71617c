// Configuration of the domain trackers, one plain struct per tracker plus DomainConfig for the
// DomainTrackers facade. The gateway's config loader maps the TOML keys to it (ride.*, faults.*,
// pack.*, telemetry.*); every default is the documented product default (docs/data-model.md).
//
// Contract: value types, no behaviour beyond validate(), which throws std::invalid_argument naming
// the offending key when a value makes no sense (e.g. a zero sampling interval).
#pragma once

#include <array>
#include <chrono>
#include <string>
#include <vector>

#include "gateway/domain/alarm_config.h"
#include "motinova/can.h"
#include "motinova/options.h"

namespace fleetgw::domain {

using motinova::Micros;
using namespace std::chrono_literals;

struct RideConfig {
  // A ride starts when the unlocked vehicle goes faster than this (ride.moving_speed_kmh).
  double moving_speed_kmh = 3.0;
  // Below this the bike stands still: no moving time, the stationary timer runs. Lower than
  // moving_speed_kmh so that a walking-pace section does not count as standing.
  double standstill_kmh = 0.5;
  // A ride standing still this long ends at the moment it stopped (ride.stationary_end_s).
  Micros stationary_end = 600s;
  // Open rides are checkpointed (upserted without uplink payload) this often.
  Micros checkpoint_interval = 30s;
  // MC silent this long during a ride: the ride is marked partial ("bus_lost").
  Micros mc_offline_timeout = 3s;
  // Longest interval integrated between two samples of the same source; longer gaps are not
  // bridged (assist time goes to "unknown", no energy, no moving time).
  Micros sample_gap = 2s;
  // BMS pack voltage x current is preferred for energy while a bms_status is this recent.
  Micros bms_fresh = 2s;
  // The MC's trip time advancing by this much (without the speed threshold being seen) also
  // starts a ride; any 0.1 km step of a trip counter does.
  double counter_start_s = 5.0;
  // Odometer steps implying a faster average speed are rejected (counter reset, MC swapped).
  double max_plausible_kmh = 80.0;
  // After a SHUTDOWN no ride starts for this long (the MC reports until power is cut, ~1 s).
  Micros shutdown_hold = 5s;
  // Prepended to the time-based ride id, e.g. the vehicle id.
  std::string ride_id_prefix;
};

struct FaultConfig {
  // A clear followed by a re-raise within this window is one episode (faults.debounce_ms).
  Micros debounce = 3s;
  // A fault word not heard this long is "unknown" (spec §3.7; the node registry's default).
  Micros stale = 2s;
  // Fault-bit names of the uncertain readings (U6, U18, U20, U22), from the decoder's options.
  std::vector<motinova::FaultNameOverride> fault_names;
};

struct PackConfig {
  Micros period = 5min;  // periodic snapshot (pack.snapshot_interval_s)
  Micros settle = 3s;    // first snapshot this long after the first bms_status (cells, temps)
  Micros stale = 5s;     // values older than this are left out of a snapshot
};

struct TelemetryConfig {
  Micros riding_interval = 1s;   // telemetry.riding_interval_ms
  Micros parked_interval = 60s;  // telemetry.parked_interval_ms
  Micros stale = 5s;             // values older than this are sampled as "not measured"
  // Lock kinds (DecodeOptions::lock_kinds) reported as the sample's wheel / battery lock state.
  std::vector<std::string> wheel_lock_kinds{"frame", "wheel", "rear_wheel"};
  std::vector<std::string> battery_lock_kinds{"battery"};
};

struct LockConfig {
  // A cause announced for a lock (command, vehicle LOCK) applies to its state changes until the
  // lock reaches a final state or this long has passed.
  Micros cause_window = 10s;
  // U21/U19 tables of the decoder (copied from DecodeOptions by apply()).
  std::array<std::string, 5> lock_kinds = motinova::DecodeOptions{}.lock_kinds;
  std::array<std::string, 7> lock_state_names = motinova::DecodeOptions{}.lock_state_names;
};

struct DomainConfig {
  RideConfig ride;
  FaultConfig faults;
  PackConfig pack;
  TelemetryConfig telemetry;
  LockConfig locks;
  // Lock kinds, command window and frame-lock kinds are taken from `locks` and `telemetry` by
  // DomainTrackers (one source of truth).
  AlarmConfig alarms;

  // Takes the lock tables from the decoder's options so names match the decoded messages.
  void apply(const motinova::DecodeOptions& options) {
    locks.lock_kinds = options.lock_kinds;
    locks.lock_state_names = options.lock_state_names;
    faults.fault_names = options.fault_names;
  }
  void validate() const;
};

}  // namespace fleetgw::domain
