// Record -> protobuf conversion: the uplink payload of every tracker output is the serialized
// fleetgw.v1 BODY message (RideRecord, FaultEvent, PackStatistics, TelemetrySample, LockEvent);
// the uplink wraps it in an Envelope with the outbox sequence number (and, for telemetry, sets
// TelemetrySample.sequence and batches samples).
//
// Contract: pure functions. Physical values are converted to the integer units of the unit rule
// in proto/fleetgw/v1/telemetry.proto by rounding to nearest; values that cannot be represented
// (negative for an unsigned field, out of range) are clamped. std::nullopt stays absent.
// The *Reading structs carry what a tracker knows beyond the storage row (the protobuf messages
// are richer than the tables), so each output is built from one source of truth.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/domain/ride_track.h"
#include "gateway/gnss/position.h"
#include "storage/records.h"

namespace fleetgw::domain {

// The fleetgw.v1.LockState number of a U19 lock state code (the LockEvent mapping, lock.proto).
int lock_state_number(int raw);

struct RideExtras {
  std::string partial_reason;                  // "gateway_restart", "bus_lost", ... or empty
  std::map<std::string, unsigned> assist_raw;  // assist name -> raw bus value, when known
  const RideTrack* track = nullptr;            // positions of the ride, when any
};
storage::Bytes ride_payload(const storage::RideRow& ride, const RideExtras& extras);

// `node_name`: motinova::node_name() of the reporter ("mc", "bms", "lock3"...).
storage::Bytes fault_payload(const storage::FaultEventRow& event, std::string_view node_name);

struct PackReading {
  storage::PackSnapshotRow snapshot;
  std::optional<double> remaining_mah;
  std::optional<double> full_mah;
  std::vector<int> cells_mv;  // populated cells, BMS order
  std::string serial;         // BMS model-info serial, empty when not heard
};
storage::Bytes pack_payload(const PackReading& reading);

struct TelemetryReading {
  std::int64_t ts_us = 0;
  std::optional<double> speed_kmh, motor_rpm, power_w, voltage_v, current_a, cadence_rpm, torque_nm,
      soc_pct, range_km, odo_km, trip_km, pcb_temp_c, motor_temp_c, mcu_temp_c, remaining_mah,
      full_mah, pack_temp_c;
  std::optional<int> assist;
  std::optional<bool> charging;
  std::optional<int> wheel_lock_state;
  std::optional<int> battery_lock_state;
  std::optional<gnss::Fix> position;  // current fix at sampling time; nullopt = unknown

  storage::TelemetryRow record() const;
};
storage::Bytes telemetry_payload(const TelemetryReading& reading);

// `old_raw`/`new_raw`: lock-state codes (U19) behind the event's state names.
// `where`: the current fix when the lock changed state (nullopt: position unknown).
storage::Bytes lock_payload(const storage::LockEventRow& event, int old_raw, int new_raw,
                            const std::optional<gnss::Fix>& where = std::nullopt);

// The fleetgw.v1.EvictionReport of one eviction pass, stored as the outbox payload of its
// report (`seq`: the report's own outbox sequence, sent as last_sequence). Serialised
// deterministically (evicted_by_kind in key order), so the stored bytes do not depend on a
// map's hash order. Given to the store as StoreOptions::encode_eviction_report.
storage::Bytes eviction_report_payload(const storage::EvictionPass& pass, std::uint64_t seq);

}  // namespace fleetgw::domain
