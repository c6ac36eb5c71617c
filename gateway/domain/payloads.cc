#include "gateway/domain/payloads.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include "fleetgw/v1/eviction.pb.h"
#include "fleetgw/v1/fault.pb.h"
#include "fleetgw/v1/lock.pb.h"
#include "fleetgw/v1/pack.pb.h"
#include "fleetgw/v1/position.pb.h"
#include "fleetgw/v1/ride.pb.h"
#include "fleetgw/v1/telemetry.pb.h"
#include "gateway/domain/wire_numbers.h"
#include "motinova/can.h"

namespace fleetgw::domain {
namespace {

using wire::s32;
using wire::u32;
using wire::u64;

void set_position(v1::Position& out, const gnss::Fix& p) {
  out.set_lat_e7(s32(p.lat_deg * 1e7));
  out.set_lon_e7(s32(p.lon_deg * 1e7));
  if (p.alt_m) out.set_alt_dm(s32(*p.alt_m * 10.0));
  if (p.hdop) out.set_hdop_centi(u32(*p.hdop * 100.0));
  if (p.horizontal_error_m) out.set_horizontal_error_dm(u32(*p.horizontal_error_m * 10.0));
  if (p.heading_deg) out.set_heading_ddeg(u32(*p.heading_deg * 10.0) % 3600);
  if (p.satellites > 0) out.set_satellites(static_cast<uint32_t>(p.satellites));
  out.set_fixed_at_us(p.fixed_at.count());
}

template <typename Message>
storage::Bytes bytes_of(const Message& m) {
  storage::Bytes out(m.ByteSizeLong());
  m.SerializeToArray(out.data(), static_cast<int>(out.size()));
  return out;
}

v1::FaultSeverity severity_of(std::string_view name) {
  if (name == "info") return v1::FAULT_SEVERITY_INFO;
  if (name == "critical") return v1::FAULT_SEVERITY_CRITICAL;
  if (name == "warning") return v1::FAULT_SEVERITY_WARNING;
  return v1::FAULT_SEVERITY_UNSPECIFIED;
}

// U19 codes to the protobuf LockState (lock.proto documents the table). The two failure codes
// share FAULT; LockEvent.state_name keeps the exact name.
v1::LockState lock_state_of(int raw) {
  switch (raw) {
    case 1:
      return v1::LOCK_STATE_UNLOCKED;
    case 2:
      return v1::LOCK_STATE_LOCKED;
    case 3:
      return v1::LOCK_STATE_UNLOCKING;
    case 4:
      return v1::LOCK_STATE_LOCKING;
    case 5:
    case 6:
      return v1::LOCK_STATE_FAULT;
    default:
      return v1::LOCK_STATE_UNSPECIFIED;
  }
}

}  // namespace

int lock_state_number(int raw) {
  return static_cast<int>(lock_state_of(raw));
}

storage::Bytes ride_payload(const storage::RideRow& r, const RideExtras& extras) {
  v1::RideRecord m;
  m.set_ride_id(r.ride_id);
  m.set_started_at_us(r.start_us);
  const int64_t end = r.end_us.value_or(r.start_us);
  m.set_ended_at_us(end);
  m.set_duration_ms(u64((end - r.start_us) / 1000.0));
  m.set_moving_time_ms(u64(r.moving_s * 1000.0));
  if (r.start_odo_km) m.set_start_odo_m(u64(*r.start_odo_km * 1000.0));
  if (r.end_odo_km) m.set_end_odo_m(u64(*r.end_odo_km * 1000.0));
  m.set_distance_odo_m(u64(r.distance_km * 1000.0));
  m.set_distance_integrated_m(u64(r.distance_integrated_km * 1000.0));
  m.set_max_speed_dkmh(u32(r.max_speed_kmh * 10.0));
  m.set_avg_speed_dkmh(u32(r.avg_speed_kmh * 10.0));
  m.set_energy_mwh(u64(r.energy_wh * 1000.0));
  m.set_energy_mah(u64(r.energy_mah));
  if (r.soc_start_pct) m.set_soc_start_pct(u32(*r.soc_start_pct));
  if (r.soc_end_pct) m.set_soc_end_pct(u32(*r.soc_end_pct));
  for (const auto& [name, seconds] : r.assist_time_s) {
    v1::AssistTime* a = m.add_assist_time();
    a->set_assist_name(name);
    if (const auto it = extras.assist_raw.find(name); it != extras.assist_raw.end()) {
      a->set_assist(it->second);
    }
    a->set_duration_ms(u64(seconds * 1000.0));
  }
  m.set_fault_count(u32(r.fault_count));
  m.set_partial(r.partial);
  if (r.partial) m.set_partial_reason(extras.partial_reason);
  if (extras.track && !extras.track->empty()) {
    const RideTrack& t = *extras.track;
    set_position(*m.mutable_start_position(), *t.start());
    set_position(*m.mutable_end_position(), *t.end());
    m.set_distance_gnss_m(u64(t.distance_m()));
    v1::Track& track = *m.mutable_track();
    track.set_tolerance_m(u32(t.tolerance_m()));
    int32_t lat = 0;
    int32_t lon = 0;
    for (const gnss::Fix& p : t.simplified()) {
      const int32_t la = s32(p.lat_deg * 1e7);
      const int32_t lo = s32(p.lon_deg * 1e7);
      track.add_lat_e7_delta(la - lat);
      track.add_lon_e7_delta(lo - lon);
      lat = la;
      lon = lo;
    }
  }
  return bytes_of(m);
}

storage::Bytes fault_payload(const storage::FaultEventRow& e, std::string_view node_name) {
  v1::FaultEvent m;
  m.set_node(std::string(node_name));
  m.set_bit(u32(e.bit));
  if (e.code >= 0) m.set_code(u32(e.code));
  m.set_name(e.name);
  m.set_severity(severity_of(e.severity));
  switch (e.event) {
    case storage::FaultEventKind::kRaised:
      m.set_kind(v1::FAULT_EVENT_KIND_RAISED);
      break;
    case storage::FaultEventKind::kCleared:
      m.set_kind(v1::FAULT_EVENT_KIND_CLEARED);
      break;
    case storage::FaultEventKind::kUnknown:
      m.set_kind(v1::FAULT_EVENT_KIND_UNKNOWN);
      break;
  }
  m.set_first_seen_us(e.first_seen_us);
  m.set_last_seen_us(e.last_seen_us);
  m.set_occurrences(u32(static_cast<double>(e.occurrences)));
  return bytes_of(m);
}

storage::Bytes pack_payload(const PackReading& p) {
  const storage::PackSnapshotRow& s = p.snapshot;
  v1::PackStatistics m;
  m.set_pack_serial(p.serial);
  m.set_measured_at_us(s.ts_us);
  if (s.voltage_v) m.set_voltage_mv(u32(*s.voltage_v * 1000.0));
  if (s.current_a) {
    // current_a is charge positive (the BMS's sign); discharge_current_ma is the wire-wide sign.
    // The deprecated field is still sent for consumers older than v1.1.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
    m.set_current_ma(s32(*s.current_a * 1000.0));
#pragma GCC diagnostic pop
    m.set_discharge_current_ma(s32(-*s.current_a * 1000.0));
  }
  if (s.soc_pct) m.set_soc_pct(u32(*s.soc_pct));
  if (s.soh_pct) m.set_soh_pct(u32(*s.soh_pct));
  if (p.remaining_mah) m.set_remaining_mah(u32(*p.remaining_mah));
  if (p.full_mah) m.set_full_mah(u32(*p.full_mah));
  if (s.cycles) m.set_cycles(u32(static_cast<double>(*s.cycles)));
  for (double t : s.temps_c) m.add_temp_c(s32(t));
  for (int mv : p.cells_mv) m.add_cells_mv(u32(mv));
  if (s.cell_min_mv) m.set_cell_min_mv(u32(*s.cell_min_mv));
  if (s.cell_max_mv) m.set_cell_max_mv(u32(*s.cell_max_mv));
  return bytes_of(m);
}

storage::TelemetryRow TelemetryReading::record() const {
  storage::TelemetryRow s;
  s.ts_us = ts_us;
  s.speed_kmh = speed_kmh;
  s.assist_level = assist;
  s.soc_pct = soc_pct;
  s.voltage_v = voltage_v;
  s.current_a = current_a;
  s.motor_temp_c = motor_temp_c;
  s.controller_temp_c = pcb_temp_c;
  s.battery_temp_c = pack_temp_c;
  s.wheel_lock_state = wheel_lock_state;
  s.battery_lock_state = battery_lock_state;
  return s;
}

storage::Bytes telemetry_payload(const TelemetryReading& r) {
  v1::TelemetrySample m;
  m.set_sampled_at_us(r.ts_us);
  if (r.speed_kmh) m.set_speed_dkmh(u32(*r.speed_kmh * 10.0));
  if (r.motor_rpm) m.set_motor_rpm(u32(*r.motor_rpm));
  if (r.power_w) m.set_power_w(s32(*r.power_w));
  if (r.voltage_v) m.set_voltage_mv(u32(*r.voltage_v * 1000.0));
  if (r.current_a) m.set_current_ma(s32(*r.current_a * 1000.0));
  if (r.cadence_rpm) m.set_cadence_rpm(u32(*r.cadence_rpm));
  if (r.torque_nm) m.set_torque_dnm(u32(*r.torque_nm * 10.0));
  if (r.assist) m.set_assist(u32(*r.assist));
  if (r.soc_pct) m.set_soc_pct(u32(*r.soc_pct));
  if (r.range_km) m.set_range_m(u32(*r.range_km * 1000.0));
  if (r.odo_km) m.set_odo_m(u64(*r.odo_km * 1000.0));
  if (r.trip_km) m.set_trip_m(u64(*r.trip_km * 1000.0));
  if (r.pcb_temp_c) m.set_pcb_temp_c(s32(*r.pcb_temp_c));
  if (r.motor_temp_c) m.set_motor_temp_c(s32(*r.motor_temp_c));
  if (r.mcu_temp_c) m.set_mcu_temp_c(s32(*r.mcu_temp_c));
  if (r.remaining_mah) m.set_remaining_mah(u32(*r.remaining_mah));
  if (r.full_mah) m.set_full_mah(u32(*r.full_mah));
  if (r.pack_temp_c) m.set_pack_temp_c(s32(*r.pack_temp_c));
  if (r.position) set_position(*m.mutable_position(), *r.position);
  return bytes_of(m);
}

storage::Bytes lock_payload(const storage::LockEventRow& e, int old_raw, int new_raw,
                            const std::optional<gnss::Fix>& where) {
  v1::LockEvent m;
  m.set_lock_kind(e.kind);
  m.set_previous_state(lock_state_of(old_raw));
  m.set_state(lock_state_of(new_raw));
  m.set_at_us(e.ts_us);
  m.set_previous_state_name(e.old_state);
  m.set_state_name(e.new_state);
  m.set_node(std::string(motinova::node_name(static_cast<motinova::Node>(e.lock_node))));
  constexpr std::string_view kCommand = "command:";
  if (e.cause.starts_with(kCommand)) {
    m.set_source(v1::LOCK_EVENT_SOURCE_REMOTE);
    m.set_command_id(e.cause.substr(kCommand.size()));
  } else if (e.cause == "local" || e.cause.starts_with("vehicle_")) {
    // The one-touch vehicle lock is operated on the vehicle (IOT button / app over BLE).
    m.set_source(v1::LOCK_EVENT_SOURCE_LOCAL);
  } else {
    m.set_source(v1::LOCK_EVENT_SOURCE_UNSPECIFIED);
  }
  if (where) set_position(*m.mutable_position(), *where);
  return bytes_of(m);
}

storage::Bytes eviction_report_payload(const storage::EvictionPass& pass, std::uint64_t seq) {
  // What the uplink used to derive from the store's JSON report on every peek, now made once.
  v1::EvictionReport report;
  report.set_evicted_records(pass.telemetry_rows + pass.pack_snapshot_rows);
  (*report.mutable_evicted_by_kind())["telemetry"] = pass.telemetry_rows;
  (*report.mutable_evicted_by_kind())["pack"] = pass.pack_snapshot_rows;
  if (pass.oldest_telemetry_kept_us)
    report.set_newest_created_at_us(*pass.oldest_telemetry_kept_us);
  report.set_reason(pass.budget_exhausted ? "disk budget exhausted" : "disk budget reached");
  report.set_last_sequence(seq);
  std::string bytes;
  {
    google::protobuf::io::StringOutputStream stream(&bytes);
    google::protobuf::io::CodedOutputStream out(&stream);
    out.SetSerializationDeterministic(true);
    report.SerializeToCodedStream(&out);
  }
  return storage::Bytes(bytes.begin(), bytes.end());
}

}  // namespace fleetgw::domain
