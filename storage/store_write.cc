// Writing a Batch: validation (bad input is named, entry and field), the one-transaction write
// with its sequence numbers, and what happens on SQLITE_FULL (storage/store.h).
#include <spdlog/spdlog.h>

#include <cmath>
#include <map>
#include <stdexcept>

#include "storage/store_impl.h"
#include "storage/track_text.h"

namespace fleetgw::storage {
namespace {

constexpr std::string_view kInsertOutbox =
    "INSERT INTO outbox (seq, priority, kind, created_us, payload, source_id) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertTelemetry =
    "INSERT INTO telemetry (ts_us, speed_kmh, assist_level, soc_pct, voltage_v, current_a, "
    "motor_temp_c, controller_temp_c, battery_temp_c, wheel_lock_state, battery_lock_state) "
    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kUpsertRide =
    "INSERT INTO rides (ride_id, state, partial, start_us, end_us, duration_s, moving_s, "
    "start_odo_km, end_odo_km, distance_km, distance_integrated_km, max_speed_kmh, "
    "avg_speed_kmh, energy_wh, energy_mah, soc_start_pct, soc_end_pct, assist_time_json, "
    "fault_count, start_lat_deg, start_lon_deg, end_lat_deg, end_lon_deg, gnss_distance_m, "
    "track) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
    "ON CONFLICT (ride_id) DO UPDATE SET state = excluded.state, partial = excluded.partial, "
    "start_us = excluded.start_us, end_us = excluded.end_us, duration_s = excluded.duration_s, "
    "moving_s = excluded.moving_s, start_odo_km = excluded.start_odo_km, "
    "end_odo_km = excluded.end_odo_km, distance_km = excluded.distance_km, "
    "distance_integrated_km = excluded.distance_integrated_km, "
    "max_speed_kmh = excluded.max_speed_kmh, avg_speed_kmh = excluded.avg_speed_kmh, "
    "energy_wh = excluded.energy_wh, energy_mah = excluded.energy_mah, "
    "soc_start_pct = excluded.soc_start_pct, soc_end_pct = excluded.soc_end_pct, "
    "assist_time_json = excluded.assist_time_json, fault_count = excluded.fault_count, "
    "start_lat_deg = excluded.start_lat_deg, start_lon_deg = excluded.start_lon_deg, "
    "end_lat_deg = excluded.end_lat_deg, end_lon_deg = excluded.end_lon_deg, "
    "gnss_distance_m = excluded.gnss_distance_m, track = excluded.track "
    "RETURNING id";
constexpr std::string_view kInsertFault =
    "INSERT INTO fault_events (node, bit, code, name, severity, event, first_seen_us, "
    "last_seen_us, occurrences) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertPack =
    "INSERT INTO pack_snapshots (ts_us, voltage_v, current_a, soc_pct, soh_pct, cycles, "
    "temps_json, cell_min_mv, cell_max_mv, cell_spread_mv, cell_min_index, cell_max_index, "
    "lifetime_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertLock =
    "INSERT INTO lock_events (ts_us, lock_node, kind, old_state, new_state, cause) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertAlarm =
    "INSERT INTO alarms (ts_us, first_evidence_us, kind, transition, lock_node, speed_kmh, "
    "max_speed_kmh, motor_rpm, soc_pct, threshold_pct, lock_fault_bits, old_bms_serial, "
    "new_bms_serial, detail) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertZoneEvent =
    "INSERT INTO zone_events (ts_us, zone_id, zone_name, kind, transition, bundle_version, "
    "lat_deg, lon_deg, speed_limit_kmh) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertCommandResult =
    "INSERT INTO command_results (command_id, ts_us, result, reason, final_state, duration_ms) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kUpsertCommand =
    "INSERT INTO commands (command_id, received_us, state, expires_at_us, command_sha256) "
    "VALUES (?, ?, ?, ?, ?) "
    "ON CONFLICT (command_id) DO UPDATE SET received_us = excluded.received_us, "
    "state = excluded.state, expires_at_us = excluded.expires_at_us, "
    "command_sha256 = coalesce(excluded.command_sha256, commands.command_sha256)";
constexpr std::string_view kUpsertSeen =
    "INSERT INTO seen_command_ids (command_id, expires_at_us) VALUES (?, ?) "
    "ON CONFLICT (command_id) DO UPDATE SET "
    "expires_at_us = max(expires_at_us, excluded.expires_at_us)";
constexpr std::string_view kUpsertMeta =
    "INSERT INTO meta (key, value) VALUES (?, ?) "
    "ON CONFLICT (key) DO UPDATE SET value = excluded.value";
std::string json_text(const std::map<std::string, double>& m) {
  return nlohmann::json(m).dump();
}
std::string json_text(const std::vector<double>& v) {
  return nlohmann::json(v).dump();
}

// ---- batch validation -----------------------------------------------------------------------

[[noreturn]] void reject(std::string_view field, std::size_t index, std::string_view member,
                         std::string_view problem) {
  throw std::invalid_argument("storage: Batch." + std::string(field) + "[" + std::to_string(index) +
                              "]." + std::string(member) + ": " + std::string(problem));
}

template <typename T>
void check_uplink(const std::vector<PendingRow<T>>& items, std::string_view field) {
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (items[i].uplink && items[i].uplink->size() > Store::kMaxPayloadBytes) {
      reject(field, i, "uplink",
             "payload of " + std::to_string(items[i].uplink->size()) + " bytes exceeds " +
                 std::to_string(Store::kMaxPayloadBytes));
    }
  }
}

void check_time(std::int64_t us, std::string_view field, std::size_t i, std::string_view member) {
  if (us < 0) reject(field, i, member, "negative timestamp " + std::to_string(us));
}

// A position is both coordinates or neither, each finite and in range.
void check_position(const std::optional<double>& lat, const std::optional<double>& lon,
                    std::string_view field, std::size_t i, std::string_view member) {
  if (lat.has_value() != lon.has_value()) {
    reject(field, i, member, "latitude and longitude must come together");
  }
  if (lat && !(std::fabs(*lat) <= 90.0 && std::fabs(*lon) <= 180.0)) {
    reject(field, i, member, "position out of range");
  }
}

void validate(const Batch& b) {
  if (b.now_us < 0) {
    throw std::invalid_argument("storage: Batch.now_us: negative timestamp " +
                                std::to_string(b.now_us));
  }
  check_uplink(b.telemetry, "telemetry");
  check_uplink(b.rides, "rides");
  check_uplink(b.faults, "faults");
  check_uplink(b.packs, "packs");
  check_uplink(b.locks, "locks");
  check_uplink(b.alarms, "alarms");
  check_uplink(b.zone_events, "zone_events");
  check_uplink(b.command_results, "command_results");
  for (std::size_t i = 0; i < b.telemetry.size(); ++i) {
    check_time(b.telemetry[i].record.ts_us, "telemetry", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.rides.size(); ++i) {
    const RideRow& r = b.rides[i].record;
    if (r.ride_id.empty()) reject("rides", i, "ride_id", "empty");
    if (r.state != RideState::kOpen && r.state != RideState::kClosed) {
      reject("rides", i, "state", "invalid value");
    }
    check_time(r.start_us, "rides", i, "start_us");
    if (r.end_us && *r.end_us < r.start_us) reject("rides", i, "end_us", "before start_us");
    check_position(r.start_lat_deg, r.start_lon_deg, "rides", i, "start_lat_deg");
    check_position(r.end_lat_deg, r.end_lon_deg, "rides", i, "end_lat_deg");
    if (r.gnss_distance_m && !(*r.gnss_distance_m >= 0 && std::isfinite(*r.gnss_distance_m))) {
      reject("rides", i, "gnss_distance_m", "not a finite distance >= 0");
    }
    if (r.track) {
      if (const auto parsed = parse_track_text(*r.track); !parsed.ok()) {
        reject("rides", i, "track", parsed.error);
      }
    }
  }
  for (std::size_t i = 0; i < b.faults.size(); ++i) {
    const FaultEventRow& f = b.faults[i].record;
    if (to_string(f.event) == "invalid") reject("faults", i, "event", "invalid value");
    check_time(f.first_seen_us, "faults", i, "first_seen_us");
    if (f.last_seen_us < f.first_seen_us) {
      reject("faults", i, "last_seen_us", "before first_seen_us");
    }
  }
  for (std::size_t i = 0; i < b.packs.size(); ++i) {
    check_time(b.packs[i].record.ts_us, "packs", i, "ts_us");
    if (!nlohmann::json::accept(b.packs[i].record.lifetime_json)) {
      reject("packs", i, "lifetime_json", "not valid JSON");
    }
  }
  for (std::size_t i = 0; i < b.locks.size(); ++i) {
    check_time(b.locks[i].record.ts_us, "locks", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.alarms.size(); ++i) {
    const AlarmRow& a = b.alarms[i].record;
    if (a.kind.empty()) reject("alarms", i, "kind", "empty");
    if (to_string(a.transition) == "invalid") reject("alarms", i, "transition", "invalid value");
    check_time(a.ts_us, "alarms", i, "ts_us");
    check_time(a.first_evidence_us, "alarms", i, "first_evidence_us");
  }
  for (std::size_t i = 0; i < b.zone_events.size(); ++i) {
    const ZoneEventRow& z = b.zone_events[i].record;
    if (z.zone_id.empty()) reject("zone_events", i, "zone_id", "empty");
    if (z.kind.empty()) reject("zone_events", i, "kind", "empty");
    if (z.transition.empty()) reject("zone_events", i, "transition", "empty");
    if (z.lat_deg.has_value() != z.lon_deg.has_value()) {
      reject("zone_events", i, "lat_deg", "latitude and longitude must come together");
    }
    check_time(z.ts_us, "zone_events", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.command_results.size(); ++i) {
    if (b.command_results[i].record.command_id.empty()) {
      reject("command_results", i, "command_id", "empty");
    }
    check_time(b.command_results[i].record.ts_us, "command_results", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.commands.size(); ++i) {
    if (b.commands[i].command_id.empty()) reject("commands", i, "command_id", "empty");
    check_time(b.commands[i].received_us, "commands", i, "received_us");
  }
  for (std::size_t i = 0; i < b.messages.size(); ++i) {
    const UplinkMessage& m = b.messages[i];
    // Campaign records live in a range of their own below every record of the product (the
    // eviction of store_budget.cc finds them there, and nothing else).
    const bool campaign = m.kind == OutboxKind::kCampaign;
    const int highest = campaign ? static_cast<int>(OutboxPriority::kCampaign) : 0;
    const int lowest = campaign ? kLowestCampaignPriority : kLowestPriority;
    if (m.priority < highest || m.priority > lowest) {
      reject("messages", i, "priority",
             std::to_string(m.priority) + " outside " + std::to_string(highest) + ".." +
                 std::to_string(lowest));
    }
    if (to_string(m.kind) == "invalid") reject("messages", i, "kind", "invalid value");
    if (m.payload.size() > Store::kMaxPayloadBytes) {
      reject("messages", i, "payload",
             std::to_string(m.payload.size()) + " bytes exceeds " +
                 std::to_string(Store::kMaxPayloadBytes));
    }
  }
  for (std::size_t i = 0; i < b.meta.size(); ++i) {
    const std::string& key = b.meta[i].first;
    if (key.empty()) reject("meta", i, "key", "empty");
    if (key.starts_with("storage.")) reject("meta", i, "key", "'" + key + "' is reserved");
  }
}

constexpr int kFullRetries = 3;

}  // namespace

void Store::Impl::enqueue(Statement& st, OutboxKind kind, int priority,
                          std::span<const std::uint8_t> payload,
                          std::optional<std::int64_t> source_id, std::int64_t now_us,
                          std::uint64_t& seq) {
  st.bind_all(static_cast<std::int64_t>(seq), priority, to_string(kind), now_us, payload,
              source_id);
  st.run();
  st.reset();
  ++seq;
}

Result<Written> Store::Impl::write(const Batch& b) {
  if (options.read_only) {
    Status error{StatusCode::kInvalid, "the store is open read-only"};
    record_failure(error, "write");
    return error;
  }
  try {
    validate(b);
  } catch (const std::invalid_argument& e) {
    Status error{StatusCode::kInvalid, e.what()};
    record_failure(error, "write");
    return error;
  }
  if (b.empty()) return Written{};
  for (int attempt = 0;; ++attempt) {
    try {
      Written result = write_once(b);
      if (attempt > 0) ++health.full_recoveries;
      record_success();
      if (wal_frames >= budget.wal_pages) checkpoint(SQLITE_CHECKPOINT_PASSIVE);
      return result;
    } catch (const std::exception& e) {
      // The transaction was rolled back: nothing of the batch is stored or numbered.
      Status error = to_status(e);
      if (error.code == StatusCode::kFull && attempt < kFullRetries &&
          evict_for_space(b.now_us, attempt + 1) > 0) {
        continue;
      }
      record_failure(error, "write");
      return error;
    }
  }
}

Written Store::Impl::write_once(const Batch& b) {
  Written result;

  Transaction tx(db);
  std::uint64_t seq = next_seq;
  auto outbox = db.cached(kInsertOutbox);
  const std::int64_t now = b.now_us;

  // Each table: insert the row, then queue its payload pointing at the new row.
  auto queue = [&](const std::optional<Bytes>& uplink, OutboxKind kind, OutboxPriority prio,
                   std::int64_t row_id) {
    if (uplink) enqueue(*outbox, kind, static_cast<int>(prio), *uplink, row_id, now, seq);
  };

  if (!b.telemetry.empty()) {
    auto st = db.cached(kInsertTelemetry);
    for (const auto& [t, uplink] : b.telemetry) {
      st->bind_all(t.ts_us, t.speed_kmh, t.assist_level, t.soc_pct, t.voltage_v, t.current_a,
                   t.motor_temp_c, t.controller_temp_c, t.battery_temp_c, t.wheel_lock_state,
                   t.battery_lock_state);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kTelemetry, OutboxPriority::kTelemetry, db.last_insert_rowid());
    }
  }
  if (!b.rides.empty()) {
    auto st = db.cached(kUpsertRide);
    for (const auto& [r, uplink] : b.rides) {
      st->bind_all(r.ride_id, to_string(r.state), r.partial, r.start_us, r.end_us, r.duration_s,
                   r.moving_s, r.start_odo_km, r.end_odo_km, r.distance_km,
                   r.distance_integrated_km, r.max_speed_kmh, r.avg_speed_kmh, r.energy_wh,
                   r.energy_mah, r.soc_start_pct, r.soc_end_pct, json_text(r.assist_time_s),
                   r.fault_count, r.start_lat_deg, r.start_lon_deg, r.end_lat_deg, r.end_lon_deg,
                   r.gnss_distance_m, r.track);
      if (!st->step()) throw std::logic_error("storage: ride upsert returned no id");
      std::int64_t id = st->column_int64(0);
      st->reset();
      queue(uplink, OutboxKind::kRide, OutboxPriority::kRide, id);
    }
  }
  if (!b.faults.empty()) {
    auto st = db.cached(kInsertFault);
    for (const auto& [f, uplink] : b.faults) {
      st->bind_all(f.node, f.bit, f.code, f.name, f.severity, to_string(f.event), f.first_seen_us,
                   f.last_seen_us, f.occurrences);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kFault, OutboxPriority::kFault, db.last_insert_rowid());
    }
  }
  if (!b.packs.empty()) {
    auto st = db.cached(kInsertPack);
    for (const auto& [p, uplink] : b.packs) {
      st->bind_all(p.ts_us, p.voltage_v, p.current_a, p.soc_pct, p.soh_pct, p.cycles,
                   json_text(p.temps_c), p.cell_min_mv, p.cell_max_mv, p.cell_spread_mv,
                   p.cell_min_index, p.cell_max_index, p.lifetime_json);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kPack, OutboxPriority::kPack, db.last_insert_rowid());
    }
  }
  if (!b.locks.empty()) {
    auto st = db.cached(kInsertLock);
    for (const auto& [l, uplink] : b.locks) {
      st->bind_all(l.ts_us, l.lock_node, l.kind, l.old_state, l.new_state, l.cause);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kLock, OutboxPriority::kLock, db.last_insert_rowid());
    }
  }
  if (!b.alarms.empty()) {
    auto st = db.cached(kInsertAlarm);
    for (const auto& [a, uplink] : b.alarms) {
      st->bind_all(a.ts_us, a.first_evidence_us, a.kind, to_string(a.transition), a.lock_node,
                   a.speed_kmh, a.max_speed_kmh, a.motor_rpm, a.soc_pct, a.threshold_pct,
                   a.lock_fault_bits, a.old_bms_serial, a.new_bms_serial, a.detail);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kAlarm, OutboxPriority::kAlarm, db.last_insert_rowid());
    }
  }
  if (!b.zone_events.empty()) {
    auto st = db.cached(kInsertZoneEvent);
    for (const auto& [z, uplink] : b.zone_events) {
      // SQLite integers are signed: a version past INT64_MAX is stored as its bit pattern.
      st->bind_all(z.ts_us, z.zone_id, z.zone_name, z.kind, z.transition,
                   static_cast<std::int64_t>(z.bundle_version), z.lat_deg, z.lon_deg,
                   z.speed_limit_kmh);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kZone, OutboxPriority::kZone, db.last_insert_rowid());
    }
  }
  if (!b.command_results.empty()) {
    auto st = db.cached(kInsertCommandResult);
    for (const auto& [c, uplink] : b.command_results) {
      st->bind_all(c.command_id, c.ts_us, c.result, c.reason, c.final_state, c.duration_ms);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kCommandResult, OutboxPriority::kCommandResult,
            db.last_insert_rowid());
    }
  }
  if (!b.commands.empty()) {
    auto journal = db.cached(kUpsertCommand);
    auto seen = db.cached(kUpsertSeen);
    for (const auto& c : b.commands) {
      journal->bind_all(c.command_id, c.received_us, c.state, c.expires_at_us);
      if (c.command_sha256.empty()) {
        journal->bind(5, nullptr);
      } else {
        journal->bind(5, std::span(reinterpret_cast<const std::uint8_t*>(c.command_sha256.data()),
                                   c.command_sha256.size()));
      }
      journal->run();
      journal->reset();
      seen->bind_all(c.command_id, c.expires_at_us);
      seen->run();
      seen->reset();
    }
  }
  for (const auto& m : b.messages) {
    enqueue(*outbox, m.kind, m.priority, m.payload, std::nullopt, now, seq);
  }
  if (!b.meta.empty()) {
    auto st = db.cached(kUpsertMeta);
    for (const auto& [key, value] : b.meta) {
      st->bind_all(key, value);
      st->run();
      st->reset();
    }
  }

  result.eviction = enforce_budget(now, *outbox, seq);

  if (seq != next_seq) {
    // The counter is persisted in the same transaction as the rows that used the numbers.
    auto st = db.cached(kUpsertMeta);
    st->bind_all(kNextSeqKey, std::to_string(seq));
    st->run();
  }
  tx.commit();

  result.first_seq = seq != next_seq ? next_seq : 0;
  result.end_seq = seq != next_seq ? seq : 0;
  result.records = b.telemetry.size() + b.rides.size() + b.faults.size() + b.packs.size() +
                   b.locks.size() + b.alarms.size() + b.command_results.size() + b.commands.size();
  next_seq = seq;  // only now: a rolled-back batch must not burn numbers in memory either
  if (result.eviction) {
    const EvictionPass& r = *result.eviction;
    log->warn(
        "storage: disk budget {} B reached on '{}' ({} -> {} B live): evicted {} "
        "telemetry samples, {} pack snapshots, {} campaign records, {} unsent outbox entries{}",
        r.budget_bytes, options.path, r.bytes_before, r.bytes_after, r.telemetry_rows,
        r.pack_snapshot_rows, r.campaign_records, r.outbox_rows,
        r.budget_exhausted ? "; NOTHING LEFT TO EVICT, database stays over budget" : "");
  }
  return result;
}

}  // namespace fleetgw::storage
