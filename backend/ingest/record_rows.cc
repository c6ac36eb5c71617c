// One function per Envelope body kind (record_rows.h): the column order of each TableSpec is
// the order of its RowBuilder calls.
#include "backend/ingest/record_rows.h"

#include <nlohmann/json.hpp>

#include "backend/ingest/json_text.h"

namespace fleetgw::ingest::rows {
namespace {
constexpr std::string_view kIgnore = "ON CONFLICT DO NOTHING";
}  // namespace

// Column lists: the order of the RowBuilder calls in the functions below.
const TableSpec kRides{"rides",
                       "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
                       "ride_id, started_at_us, ended_at_us, duration_ms, moving_time_ms, "
                       "start_odo_m, end_odo_m, distance_odo_m, distance_integrated_m, "
                       "distance_gnss_m, max_speed_dkmh, avg_speed_dkmh, energy_mwh, energy_mah, "
                       "soc_start_pct, soc_end_pct, fault_count, partial, partial_reason, "
                       "start_lat_e7, start_lon_e7, end_lat_e7, end_lon_e7",
                       28, kIgnore};
const TableSpec kFaults{"fault_events",
                        "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, node, "
                        "bit, code, name, severity, kind, first_seen_us, last_seen_us, occurrences",
                        14, kIgnore};
const TableSpec kTelemetry{
    "telemetry_samples",
    "vehicle_id, store_id, sequence, created_at_us, sampled_at_us, speed_dkmh, motor_rpm, "
    "power_w, voltage_mv, current_ma, cadence_rpm, torque_dnm, assist, soc_pct, range_m, odo_m, "
    "trip_m, pcb_temp_c, motor_temp_c, mcu_temp_c, remaining_mah, full_mah, pack_temp_c, lat_e7, "
    "lon_e7, horizontal_error_dm, heading_ddeg",
    27, kIgnore};
const TableSpec kPacks{"pack_snapshots",
                       "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
                       "pack_serial, measured_at_us, voltage_mv, discharge_current_ma, soc_pct, "
                       "soh_pct, remaining_mah, full_mah, cycles, temp_c, cells_mv, cell_min_mv, "
                       "cell_max_mv",
                       18, kIgnore};
const TableSpec kLocks{"lock_events",
                       "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, node, "
                       "lock_kind, previous_state, state, previous_state_name, state_name, source, "
                       "at_us, command_id, lat_e7, lon_e7",
                       16, kIgnore};
const TableSpec kResults{"command_results",
                         "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
                         "command_id, result, reason, final_lock_state_name, duration_ms, stored, "
                         "mc_action, command_sha256",
                         13, kIgnore};
const TableSpec kCommands{"commands",
                          "command_id, vehicle_id, key_id, issued_at_us, expires_at_us, action, "
                          "target",
                          7, kIgnore};
const TableSpec kInfo{"device_info",
                      "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, nodes", 6,
                      kIgnore};
const TableSpec kAlarms{"alarms",
                        "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, kind, "
                        "transition, at_us, first_evidence_us, speed_dkmh, soc_pct, lock_kind, "
                        "detail",
                        13, kIgnore};
const TableSpec kEvictions{"evictions",
                           "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
                           "evicted_records, first_sequence, last_sequence, oldest_created_at_us, "
                           "newest_created_at_us, by_kind, reason",
                           12, kIgnore};
// Latest wins: a retained status is delivered again at every subscribe.
const TableSpec kStatus{
    "status",
    "vehicle_id, created_at_us, online, connection, outbox_depth, bus_state, firmware_version, "
    "last_will, attention, publish_refusals, last_publish_refusal, last_publish_refusal_code, "
    "last_publish_refusal_at_us",
    13,
    "ON CONFLICT (vehicle_id) DO UPDATE SET received_at_us = fleet_now_us(), created_at_us = "
    "EXCLUDED.created_at_us, online = EXCLUDED.online, connection = EXCLUDED.connection, "
    "outbox_depth = EXCLUDED.outbox_depth, bus_state = EXCLUDED.bus_state, firmware_version = "
    "EXCLUDED.firmware_version, last_will = EXCLUDED.last_will, attention = EXCLUDED.attention, "
    "publish_refusals = EXCLUDED.publish_refusals, last_publish_refusal = "
    "EXCLUDED.last_publish_refusal, last_publish_refusal_code = "
    "EXCLUDED.last_publish_refusal_code, last_publish_refusal_at_us = "
    "EXCLUDED.last_publish_refusal_at_us",
    true};
const TableSpec kZones{"zone_events",
                       "vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
                       "zone_id, zone_name, kind, transition, at_us, lat_e7, lon_e7, "
                       "bundle_version, speed_limit_kmh",
                       14, kIgnore};
// A state older than the stored one (a late duplicate) does not replace it, unless the stored one
// claims a time more than 10 minutes ahead of the database's clock: a gateway whose clock was
// wrong once must not freeze its vehicle's state for ever (issue 24).
const TableSpec kState{
    "vehicle_state",
    "vehicle_id, updated_at_us, online, mode, soc_pct, range_m, odo_m, lat_e7, lon_e7, locks, "
    "faults, active_alarms, speed_limit_dkmh, assist, assist_name, bus_state, "
    "position_fixed_at_us, horizontal_error_dm, heading_ddeg",
    19,
    "ON CONFLICT (vehicle_id) DO UPDATE SET received_at_us = fleet_now_us(), updated_at_us = "
    "EXCLUDED.updated_at_us, online = EXCLUDED.online, mode = EXCLUDED.mode, soc_pct = "
    "EXCLUDED.soc_pct, range_m = EXCLUDED.range_m, odo_m = EXCLUDED.odo_m, lat_e7 = "
    "EXCLUDED.lat_e7, lon_e7 = EXCLUDED.lon_e7, locks = EXCLUDED.locks, faults = "
    "EXCLUDED.faults, active_alarms = EXCLUDED.active_alarms, speed_limit_dkmh = "
    "EXCLUDED.speed_limit_dkmh, assist = EXCLUDED.assist, assist_name = EXCLUDED.assist_name, "
    "bus_state = EXCLUDED.bus_state, position_fixed_at_us = EXCLUDED.position_fixed_at_us, "
    "horizontal_error_dm = EXCLUDED.horizontal_error_dm, heading_ddeg = EXCLUDED.heading_ddeg "
    "WHERE EXCLUDED.updated_at_us >= vehicle_state.updated_at_us OR "
    "vehicle_state.updated_at_us > fleet_now_us() + 600000000",
    true};
// Every status whose (online, last_will) differs from the vehicle's latest history row
// (migration 4); a redelivered status conflicts on its key. The statement's own rows are not
// visible to its NOT EXISTS: two statuses of one vehicle in one batch may both be kept even
// with the same state (readers take changes, docs/backend.md "Schema").
const TableSpec kStatusHistory{
    "status_history",
    "vehicle_id, created_at_us, online, last_will, connection, connected_at_us",
    6,
    "WHERE NOT EXISTS (SELECT 1 FROM (SELECT h.online, h.last_will FROM status_history h WHERE "
    "h.vehicle_id = u.c0 ORDER BY h.id DESC LIMIT 1) l WHERE l.online = u.c2 AND l.last_will "
    "= u.c3::boolean) ON CONFLICT DO NOTHING",
    false,
    true};

RowSet& new_rows(Decoded& d, const TableSpec& t, std::size_t rows) {
  d.rows.push_back(RowSet{&t, {}, 0});
  // Sized once for the usual row (a few bytes per value and the two ids): growing it copies
  // everything built so far.
  d.rows.back().copy.reserve(rows * (static_cast<std::size_t>(t.column_count) * 6 + 64));
  return d.rows.back();
}

void ride_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::RideRecord& r = e.ride();
  Header{e}.add(b);
  b.text("ride_id", r.ride_id());
  b.i64(r.started_at_us());
  b.i64(r.ended_at_us());
  b.u64("duration_ms", r.duration_ms());
  b.u64("moving_time_ms", r.moving_time_ms());
  b.u64("start_odo_m", r.start_odo_m());
  b.u64("end_odo_m", r.end_odo_m());
  b.u64("distance_odo_m", r.distance_odo_m());
  b.u64("distance_integrated_m", r.distance_integrated_m());
  b.opt_u64("distance_gnss_m", r.has_distance_gnss_m(), r.distance_gnss_m());
  b.u32("max_speed_dkmh", r.max_speed_dkmh());
  b.u32("avg_speed_dkmh", r.avg_speed_dkmh());
  b.u64("energy_mwh", r.energy_mwh());
  b.u64("energy_mah", r.energy_mah());
  b.opt_u32("soc_start_pct", r.has_soc_start_pct(), r.soc_start_pct());
  b.opt_u32("soc_end_pct", r.has_soc_end_pct(), r.soc_end_pct());
  b.u32("fault_count", r.fault_count());
  b.boolean(r.partial());
  b.text("partial_reason", r.partial_reason());
  b.position(r.has_start_position(), r.start_position());
  b.position(r.has_end_position(), r.end_position());
  d.records = 1;
}

void fault_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::FaultEvent& f = e.fault();
  Header{e}.add(b);
  b.text("node", f.node());
  b.u32("bit", f.bit());
  b.opt_u32("code", f.has_code(), f.code());
  b.text("name", f.name());
  b.name(&v1::FaultSeverity_Name<v1::FaultSeverity>, f.severity());
  b.name(&v1::FaultEventKind_Name<v1::FaultEventKind>, f.kind());
  b.i64(f.first_seen_us());
  b.i64(f.last_seen_us());
  b.u32("occurrences", f.occurrences());
  d.records = 1;
}

void pack_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::PackStatistics& p = e.pack();
  Header{e}.add(b);
  b.text("pack_serial", p.pack_serial());
  b.i64(p.measured_at_us());
  b.opt_u32("voltage_mv", p.has_voltage_mv(), p.voltage_mv());
  // Gateways before v1.1 send only the BMS's own sign (charge positive): reading that
  // deprecated field is the point here.
  if (p.has_discharge_current_ma()) {
    b.i64(p.discharge_current_ma());
  } else {
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
    b.opt_i64(p.has_current_ma(), -static_cast<std::int64_t>(p.current_ma()));
#pragma GCC diagnostic pop
  }
  b.opt_u32("soc_pct", p.has_soc_pct(), p.soc_pct());
  b.opt_u32("soh_pct", p.has_soh_pct(), p.soh_pct());
  b.opt_u32("remaining_mah", p.has_remaining_mah(), p.remaining_mah());
  b.opt_u32("full_mah", p.has_full_mah(), p.full_mah());
  b.opt_u32("cycles", p.has_cycles(), p.cycles());
  std::string temps = "{";
  for (int i = 0; i < p.temp_c_size(); ++i) temps += (i ? "," : "") + std::to_string(p.temp_c(i));
  b.raw(temps + "}");
  std::string cells = "{";
  for (int i = 0; i < p.cells_mv_size(); ++i) {
    if (p.cells_mv(i) > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max())) {
      b.fail("value_out_of_range", fmt::format("cells_mv[{}]: {} above 2^31-1", i, p.cells_mv(i)));
    }
    cells += (i ? "," : "") + std::to_string(p.cells_mv(i));
  }
  b.raw(cells + "}");
  b.opt_u32("cell_min_mv", p.has_cell_min_mv(), p.cell_min_mv());
  b.opt_u32("cell_max_mv", p.has_cell_max_mv(), p.cell_max_mv());
  d.records = 1;
}

void lock_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::LockEvent& l = e.lock();
  Header{e}.add(b);
  b.text("node", l.node());
  b.text("lock_kind", l.lock_kind());
  b.name(&v1::LockState_Name<v1::LockState>, l.previous_state());
  b.name(&v1::LockState_Name<v1::LockState>, l.state());
  b.text("previous_state_name", l.previous_state_name());
  b.text("state_name", l.state_name());
  b.name(&v1::LockEventSource_Name<v1::LockEventSource>, l.source());
  b.i64(l.at_us());
  b.text("command_id", l.command_id());
  b.position(l.has_position(), l.position());
  d.records = 1;
}

namespace {

std::string bytea_hex(std::string_view bytes) {
  std::string out = "\\x";
  for (unsigned char c : bytes) out += fmt::format("{:02x}", c);
  return out;
}

}  // namespace

void result_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::CommandResult& r = e.command_result();
  Header{e}.add(b);
  b.text("command_id", r.command_id());
  b.name(&v1::CommandResultCode_Name<v1::CommandResultCode>, r.result());
  b.text("reason", r.reason());
  b.text("final_lock_state_name", r.final_lock_state_name());
  b.u64("duration_ms", r.duration_ms());
  b.boolean(r.stored());
  b.text("mc.action", r.mc().action());
  if (r.command_sha256().size() > 64) {
    b.fail("text_too_long", fmt::format("command_sha256: {} bytes", r.command_sha256().size()));
  }
  r.command_sha256().empty() ? b.null() : b.raw(bytea_hex(r.command_sha256()));
  d.records = e.sequence() > 0 ? 1 : 0;
}

void info_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  Header{e}.add(b);
  std::string nodes;
  JsonWriter j(nodes);
  j.begin_array();
  for (const v1::NodeInfo& n : e.info().nodes()) {
    for (std::string_view s : {n.node(), n.model(), n.serial(), n.hw_version(), n.fw_version()}) {
      if (s.size() > kMaxText || s.find('\0') != std::string_view::npos) {
        b.fail("bad_text", "info.nodes: a field too long or with a NUL byte");
      }
    }
    // Keys in nlohmann::json's (sorted) order: the text the ingest always wrote.
    j.begin_object();
    j.key("fw_version");
    j.string(n.fw_version());
    j.key("hw_version");
    j.string(n.hw_version());
    j.key("model");
    j.string(n.model());
    j.key("node");
    j.string(n.node());
    j.key("serial");
    j.string(n.serial());
    j.end_object();
  }
  j.end_array();
  b.raw(nodes);
  d.records = 1;
}

void alarm_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::Alarm& a = e.alarm();
  Header{e}.add(b);
  b.name(&v1::AlarmKind_Name<v1::AlarmKind>, a.kind());
  b.name(&v1::AlarmTransition_Name<v1::AlarmTransition>, a.transition());
  b.i64(a.at_us());
  b.i64(a.first_evidence_us());
  b.opt_u32("speed_dkmh", a.has_speed_dkmh(), a.speed_dkmh());
  b.opt_u32("soc_pct", a.has_soc_pct(), a.soc_pct());
  b.text("lock_kind", a.lock_kind());
  b.text("detail", a.detail());
  d.records = 1;
}

void eviction_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::EvictionReport& r = e.eviction();
  Header{e}.add(b);
  b.u64("evicted_records", r.evicted_records());
  b.u64("first_sequence", r.first_sequence());
  b.u64("last_sequence", r.last_sequence());
  b.i64(r.oldest_created_at_us());
  b.i64(r.newest_created_at_us());
  nlohmann::json by_kind = nlohmann::json::object();
  for (const auto& [kind, n] : r.evicted_by_kind()) {
    if (kind.size() > kMaxText || kind.find('\0') != std::string::npos) {
      b.fail("bad_text", "eviction.evicted_by_kind: a key too long or with a NUL byte");
    }
    by_kind[kind] = n;
  }
  b.raw(by_kind.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  b.text("reason", r.reason());
  if (r.first_sequence() == 0 || r.last_sequence() < r.first_sequence()) {
    b.fail("bad_eviction_range", fmt::format("eviction: [{}, {}] is not a range of sequences",
                                             r.first_sequence(), r.last_sequence()));
  } else {
    d.ranges.push_back({r.first_sequence(), r.last_sequence()});
  }
  d.records = 1;
}

void status_rows(const v1::Envelope& e, RowBuilder& b) {
  const v1::Status& s = e.status();
  b.text("vehicle_id", e.vehicle_id());
  b.i64(e.created_at_us());
  b.name(&v1::OnlineState_Name<v1::OnlineState>, s.state());
  b.name(&v1::ConnectionState_Name<v1::ConnectionState>, s.connection());
  b.u64("outbox_depth", s.outbox_depth());
  b.name(&v1::BusState_Name<v1::BusState>, s.bus_state());
  b.text("firmware_version", s.firmware_version());
  b.boolean(s.last_will());
  // A PostgreSQL array literal: each element double-quoted, `"` and `\` backslash-escaped and
  // every other byte (newline included) kept as it is, so the stored text is the sent text.
  std::string array = "{";
  for (const std::string& a : s.attention()) {
    if (a.size() > kMaxText || a.find('\0') != std::string::npos) {
      b.fail("bad_text", "status.attention: an entry too long or with a NUL byte");
    }
    array += array.size() > 1 ? ",\"" : "\"";
    for (char c : a) {
      if (c == '"' || c == '\\') array += '\\';
      array += c;
    }
    array += '"';
  }
  b.raw(array + "}");
  b.u64("status.publish_refusals", s.publish_refusals());
  b.text("status.last_publish_refusal", s.last_publish_refusal());
  b.u32("status.last_publish_refusal_code", s.last_publish_refusal_code());
  b.i64(s.last_publish_refusal_at_us());
}

// A zone event names its zone: an event without a zone id, kind or transition is malformed (a
// gateway never sends one), not a row nobody could group by zone.
void zone_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b) {
  const v1::ZoneEvent& z = e.zone();
  Header{e}.add(b);
  if (z.zone_id().empty()) b.fail("bad_zone_event", "zone.zone_id is empty");
  if (z.kind() == v1::ZONE_KIND_UNSPECIFIED) {
    b.fail("bad_zone_event", "zone.kind is ZONE_KIND_UNSPECIFIED");
  }
  if (z.transition() == v1::ZONE_TRANSITION_UNSPECIFIED) {
    b.fail("bad_zone_event", "zone.transition is ZONE_TRANSITION_UNSPECIFIED");
  }
  b.text("zone.zone_id", z.zone_id());
  b.text("zone.zone_name", z.zone_name());
  b.name(&v1::ZoneKind_Name<v1::ZoneKind>, z.kind());
  b.name(&v1::ZoneTransition_Name<v1::ZoneTransition>, z.transition());
  b.i64(z.at_us());
  b.position(z.has_position(), z.position());
  b.u64("zone.bundle_version", z.bundle_version());
  b.u32("zone.speed_limit_kmh", z.speed_limit_kmh());
  d.records = 1;
}

// A text[] literal of enum names (names only: no quoting needed, quoted all the same).
std::string name_array(const std::vector<std::string>& names) {
  std::string array = "{";
  for (const std::string& n : names) array += (array.size() > 1 ? ",\"" : "\"") + n + "\"";
  return array + "}";
}

// Strings of a state's lock or fault entry: checked as every received text is.
void check_entry_text(RowBuilder& b, std::string_view field, std::string_view s) {
  if (s.size() > kMaxText) {
    b.fail("text_too_long", fmt::format("{}: {} bytes (at most {})", field, s.size(), kMaxText));
  } else if (s.find('\0') != std::string_view::npos) {
    b.fail("nul_in_text", fmt::format("{}: NUL byte in \"{}\"", field, untrusted_excerpt(s)));
  }
}

void state_rows(const v1::Envelope& e, RowBuilder& b) {
  const v1::VehicleState& s = e.state();
  b.text("vehicle_id", e.vehicle_id());
  b.i64(s.updated_at_us());
  b.boolean(s.online());
  b.name(&v1::VehicleMode_Name<v1::VehicleMode>, s.mode());
  b.opt_u32("soc_pct", s.has_soc_pct(), s.soc_pct());
  b.opt_u32("range_m", s.has_range_m(), s.range_m());
  b.opt_u64("odo_m", s.has_odo_m(), s.odo_m());
  b.position(s.has_position(), s.position());
  // A state names each lock and fault of the bike (a handful); more than kMaxStateEntries is
  // not a bike's, and would make rows of megabytes.
  if (s.locks_size() > kMaxStateEntries || s.faults_size() > kMaxStateEntries ||
      s.active_alarms_size() > kMaxStateEntries) {
    b.fail("too_many_entries",
           fmt::format("state: {} locks, {} faults, {} alarms (at most {} each)", s.locks_size(),
                       s.faults_size(), s.active_alarms_size(), kMaxStateEntries));
  }
  // Written as JSON text directly (json_text.h), keys sorted as nlohmann::json wrote them;
  // invalid UTF-8 (a non-proto3 sender) becomes U+FFFD: jsonb accepts only valid text.
  std::string json;
  json.reserve(64 + 96 * static_cast<std::size_t>(s.locks_size() + s.faults_size()));
  JsonWriter j(json);
  j.begin_array();
  for (const v1::VehicleLock& l : s.locks()) {
    check_entry_text(b, "state.locks.node", l.node());
    check_entry_text(b, "state.locks.kind", l.kind());
    check_entry_text(b, "state.locks.state_name", l.state_name());
    j.begin_object();
    j.key("kind");
    j.string(l.kind());
    j.key("node");
    j.string(l.node());
    j.key("state");
    const std::string& state = v1::LockState_Name(static_cast<v1::LockState>(l.state()));
    if (state.empty()) {
      j.string(std::to_string(l.state()));  // a state newer than this ingest, as a string
    } else {
      j.string(state);
    }
    j.key("state_name");
    j.string(l.state_name());
    j.end_object();
  }
  j.end_array();
  b.raw(json);
  json.clear();
  JsonWriter jf(json);  // a new array: no comma before it
  jf.begin_array();
  for (const v1::VehicleFault& f : s.faults()) {
    check_entry_text(b, "state.faults.node", f.node());
    check_entry_text(b, "state.faults.name", f.name());
    check_entry_text(b, "state.faults.severity", f.severity());
    jf.begin_object();
    jf.key("code");
    f.has_code() ? jf.number(f.code()) : jf.null();
    jf.key("name");
    jf.string(f.name());
    jf.key("node");
    jf.string(f.node());
    jf.key("severity");
    jf.string(f.severity());
    jf.end_object();
  }
  jf.end_array();
  b.raw(json);
  std::vector<std::string> alarms;
  for (int a : s.active_alarms())
    alarms.push_back(enum_name(&v1::AlarmKind_Name<v1::AlarmKind>, a));
  b.raw(name_array(alarms));
  b.opt_u32("state.speed_limit_dkmh", s.has_speed_limit_dkmh(), s.speed_limit_dkmh());
  b.opt_u32("state.assist", s.has_assist(), s.assist());
  b.text("state.assist_name", s.assist_name());
  b.name(&v1::BusState_Name<v1::BusState>, s.bus_state());
  const v1::Position& p = s.position();
  b.opt_i64(s.has_position() && p.fixed_at_us() != 0, p.fixed_at_us());
  b.opt_u32("state.position.horizontal_error_dm", s.has_position() && p.has_horizontal_error_dm(),
            p.horizontal_error_dm());
  b.opt_u32("state.position.heading_ddeg", s.has_position() && p.has_heading_ddeg(),
            p.heading_ddeg());
}

void status_history_rows(const v1::Envelope& e, Decoded& d) {
  const v1::Status& s = e.status();
  RowSet& rows = new_rows(d, kStatusHistory);
  RowBuilder b(rows);
  b.text("vehicle_id", e.vehicle_id());
  b.i64(e.created_at_us());
  b.name(&v1::OnlineState_Name<v1::OnlineState>, s.state());
  b.boolean(s.last_will());
  b.name(&v1::ConnectionState_Name<v1::ConnectionState>, s.connection());
  b.opt_i64(s.connected_at_us() != 0, s.connected_at_us());
}

std::optional<Reject> telemetry_rows(const v1::Envelope& e, Decoded& d) {
  if (static_cast<std::size_t>(e.telemetry().samples_size()) > kMaxSamples) {
    // Checked before any row is built: rows cost ~1 KB per sample in memory (issue 24).
    return Reject{"too_many_samples", fmt::format("telemetry batch of {} samples (at most {})",
                                                  e.telemetry().samples_size(), kMaxSamples)};
  }
  RowSet& rows = new_rows(d, kTelemetry, static_cast<std::size_t>(e.telemetry().samples_size()));
  RowBuilder b(rows);
  // The ids lead every sample's row: checked and escaped once per message.
  b.check_text("vehicle_id", e.vehicle_id());
  b.check_text("store_id", e.store_id());
  std::string ids;
  append_copy_text(ids, e.vehicle_id());
  ids += '\t';
  append_copy_text(ids, e.store_id());
  std::vector<std::uint64_t> seqs;
  seqs.reserve(e.telemetry().samples_size());
  for (const v1::TelemetrySample& s : e.telemetry().samples()) {
    if (s.sequence() == 0) {
      return Reject{"record_without_sequence",
                    fmt::format("telemetry sample {} has sequence 0", seqs.size())};
    }
    b.escaped(ids, 2);
    b.u64("samples.sequence", s.sequence());
    b.i64(e.created_at_us());
    b.i64(s.sampled_at_us());
    b.opt_u32("speed_dkmh", s.has_speed_dkmh(), s.speed_dkmh());
    b.opt_u32("motor_rpm", s.has_motor_rpm(), s.motor_rpm());
    b.opt_i64(s.has_power_w(), s.power_w());
    b.opt_u32("voltage_mv", s.has_voltage_mv(), s.voltage_mv());
    b.opt_i64(s.has_current_ma(), s.current_ma());
    b.opt_u32("cadence_rpm", s.has_cadence_rpm(), s.cadence_rpm());
    b.opt_u32("torque_dnm", s.has_torque_dnm(), s.torque_dnm());
    b.opt_u32("assist", s.has_assist(), s.assist());
    b.opt_u32("soc_pct", s.has_soc_pct(), s.soc_pct());
    b.opt_u32("range_m", s.has_range_m(), s.range_m());
    b.opt_u64("odo_m", s.has_odo_m(), s.odo_m());
    b.opt_u64("trip_m", s.has_trip_m(), s.trip_m());
    b.opt_i64(s.has_pcb_temp_c(), s.pcb_temp_c());
    b.opt_i64(s.has_motor_temp_c(), s.motor_temp_c());
    b.opt_i64(s.has_mcu_temp_c(), s.mcu_temp_c());
    b.opt_u32("remaining_mah", s.has_remaining_mah(), s.remaining_mah());
    b.opt_u32("full_mah", s.has_full_mah(), s.full_mah());
    b.opt_i64(s.has_pack_temp_c(), s.pack_temp_c());
    b.position(s.has_position(), s.position());
    const v1::Position& fix = s.position();  // migration 8: MDS telemetry's heading, accuracy
    b.opt_u32("samples.position.horizontal_error_dm",
              s.has_position() && fix.has_horizontal_error_dm(), fix.horizontal_error_dm());
    b.opt_u32("samples.position.heading_ddeg", s.has_position() && fix.has_heading_ddeg(),
              fix.heading_ddeg());
    seqs.push_back(s.sequence());
  }
  if (b.error) return b.error;
  if (seqs.empty()) return Reject{"empty_telemetry", "telemetry batch without samples"};
  d.records = seqs.size();
  d.ranges = to_ranges(std::move(seqs));
  return std::nullopt;
}
}  // namespace fleetgw::ingest::rows
