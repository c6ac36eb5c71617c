#include "storage/schema.h"

#include <spdlog/spdlog.h>

#include <array>
#include <string_view>

namespace fleetgw::storage {
namespace {

// v1: the base tables. Frozen: a released step is never edited, later changes are new steps.
constexpr std::string_view kV1 = R"sql(
CREATE TABLE rides (
  id INTEGER PRIMARY KEY,
  ride_id TEXT NOT NULL UNIQUE,
  state TEXT NOT NULL CHECK (state IN ('open', 'closed')),
  partial INTEGER NOT NULL DEFAULT 0,
  start_us INTEGER NOT NULL,
  end_us INTEGER,
  duration_s REAL NOT NULL DEFAULT 0,
  moving_s REAL NOT NULL DEFAULT 0,
  start_odo_km REAL,
  end_odo_km REAL,
  distance_km REAL NOT NULL DEFAULT 0,
  distance_integrated_km REAL NOT NULL DEFAULT 0,
  max_speed_kmh REAL NOT NULL DEFAULT 0,
  avg_speed_kmh REAL NOT NULL DEFAULT 0,
  energy_wh REAL NOT NULL DEFAULT 0,
  energy_mah REAL NOT NULL DEFAULT 0,
  soc_start_pct INTEGER,
  soc_end_pct INTEGER,
  assist_time_json TEXT NOT NULL DEFAULT '{}',
  fault_count INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE fault_events (
  id INTEGER PRIMARY KEY,
  node INTEGER NOT NULL,
  bit INTEGER NOT NULL,
  code INTEGER NOT NULL,
  name TEXT NOT NULL,
  severity TEXT NOT NULL,
  event TEXT NOT NULL CHECK (event IN ('raised', 'cleared', 'unknown')),
  first_seen_us INTEGER NOT NULL,
  last_seen_us INTEGER NOT NULL,
  occurrences INTEGER NOT NULL DEFAULT 1
);
CREATE TABLE pack_snapshots (
  id INTEGER PRIMARY KEY,
  ts_us INTEGER NOT NULL,
  voltage_v REAL,
  current_a REAL,
  soc_pct REAL,
  soh_pct REAL,
  cycles INTEGER,
  temps_json TEXT NOT NULL DEFAULT '[]',
  cell_min_mv INTEGER,
  cell_max_mv INTEGER,
  cell_spread_mv INTEGER,
  cell_min_index INTEGER,
  cell_max_index INTEGER,
  lifetime_json TEXT NOT NULL DEFAULT '{}'
);
CREATE TABLE telemetry (
  id INTEGER PRIMARY KEY,
  ts_us INTEGER NOT NULL,
  speed_kmh REAL,
  assist_level INTEGER,
  soc_pct REAL,
  voltage_v REAL,
  current_a REAL,
  motor_temp_c REAL,
  controller_temp_c REAL,
  battery_temp_c REAL,
  wheel_lock_state INTEGER,
  battery_lock_state INTEGER
);
CREATE TABLE lock_events (
  id INTEGER PRIMARY KEY,
  ts_us INTEGER NOT NULL,
  lock_node INTEGER NOT NULL,
  kind TEXT NOT NULL,
  old_state TEXT NOT NULL,
  new_state TEXT NOT NULL,
  cause TEXT NOT NULL
);
CREATE TABLE command_results (
  id INTEGER PRIMARY KEY,
  command_id TEXT NOT NULL,
  ts_us INTEGER NOT NULL,
  result TEXT NOT NULL,
  reason TEXT NOT NULL,
  final_state TEXT NOT NULL,
  duration_ms INTEGER NOT NULL
);
CREATE TABLE commands (
  command_id TEXT PRIMARY KEY,
  received_us INTEGER NOT NULL,
  state TEXT NOT NULL,
  expires_at_us INTEGER NOT NULL
);
CREATE TABLE seen_command_ids (
  command_id TEXT PRIMARY KEY,
  expires_at_us INTEGER NOT NULL
);
CREATE TABLE meta (
  key TEXT PRIMARY KEY,
  value TEXT NOT NULL
);
CREATE TABLE outbox (
  seq INTEGER PRIMARY KEY,
  priority INTEGER NOT NULL,
  kind TEXT NOT NULL,
  created_us INTEGER NOT NULL,
  payload BLOB NOT NULL,
  source_id INTEGER
);
)sql";

// v2: persisted eviction counters, and the indexes the uplink and the eviction need once the
// outbox holds days of backlog (v1 sorted the whole outbox on every peek).
constexpr std::string_view kV2 = R"sql(
CREATE TABLE eviction_counters (
  table_name TEXT PRIMARY KEY,
  rows INTEGER NOT NULL DEFAULT 0,
  passes INTEGER NOT NULL DEFAULT 0,
  last_us INTEGER
);
INSERT INTO eviction_counters (table_name) VALUES ('telemetry'), ('pack_snapshots'), ('outbox');
CREATE INDEX outbox_by_priority ON outbox (priority, seq);
CREATE INDEX outbox_by_source ON outbox (kind, source_id) WHERE source_id IS NOT NULL;
)sql";

// v3: the journal keeps the SHA-256 of the signed command bytes (nullable: rows of older
// versions have none), so recovery after a restart answers bound to the command.
constexpr std::string_view kV3 = R"sql(
ALTER TABLE commands ADD COLUMN command_sha256 BLOB;
)sql";

// v4: operator alarms (gateway/domain/alarm_tracker.h), never evicted.
constexpr std::string_view kV4 = R"sql(
CREATE TABLE alarms (
  id INTEGER PRIMARY KEY,
  ts_us INTEGER NOT NULL,
  first_evidence_us INTEGER NOT NULL,
  kind TEXT NOT NULL,
  transition TEXT NOT NULL CHECK (transition IN ('raised', 'cleared')),
  lock_node INTEGER,
  speed_kmh REAL,
  max_speed_kmh REAL,
  motor_rpm REAL,
  soc_pct REAL,
  threshold_pct INTEGER,
  lock_fault_bits INTEGER,
  old_bms_serial TEXT NOT NULL DEFAULT '',
  new_bms_serial TEXT NOT NULL DEFAULT '',
  detail TEXT NOT NULL DEFAULT ''
);
CREATE INDEX alarms_by_time ON alarms (ts_us);
)sql";

// v5: geofence events (gateway/geofence/zone_engine.h ZoneEvent), never evicted.
constexpr std::string_view kV5 = R"sql(
CREATE TABLE zone_events (
  id INTEGER PRIMARY KEY,
  ts_us INTEGER NOT NULL,
  zone_id TEXT NOT NULL,
  zone_name TEXT NOT NULL DEFAULT '',
  kind TEXT NOT NULL,
  transition TEXT NOT NULL,
  bundle_version INTEGER NOT NULL,
  lat_deg REAL,
  lon_deg REAL,
  speed_limit_kmh INTEGER
);
CREATE INDEX zone_events_by_time ON zone_events (ts_us);
)sql";

// v6: where a ride went (issue 14), NULL when the ride had no GNSS fix. `track` is the
// simplified polyline (every fix within 5 m of it) as a JSON array of [longitude, latitude]
// positions in degrees, 1e-7 precision: GeoJSON's coordinate order and syntax
// (storage/track_text.h).
constexpr std::string_view kV6 = R"sql(
ALTER TABLE rides ADD COLUMN start_lat_deg REAL;
ALTER TABLE rides ADD COLUMN start_lon_deg REAL;
ALTER TABLE rides ADD COLUMN end_lat_deg REAL;
ALTER TABLE rides ADD COLUMN end_lon_deg REAL;
ALTER TABLE rides ADD COLUMN gnss_distance_m REAL;
ALTER TABLE rides ADD COLUMN track TEXT;
)sql";

// v7: the outbox keeps one index. `outbox_by_source` was read only when the disk budget evicts
// telemetry or pack snapshots, yet every queued record paid a third B-tree insert for it (a
// fifth of the CPU of a replayed worst-case hour). Eviction now finds the evicted rows' entries
// through `outbox_by_priority`: telemetry and pack snapshots each have a priority of their own,
// and within one kind the entries are queued in the order of their rows (storage/store_budget.cc).
constexpr std::string_view kV7 = R"sql(
DROP INDEX outbox_by_source;
)sql";

constexpr std::array<std::string_view, kSchemaVersion> kSteps = {kV1, kV2, kV3, kV4, kV5, kV6, kV7};

}  // namespace

SchemaTooNewError::SchemaTooNewError(const std::string& path, int found, int supported)
    : std::runtime_error("storage: database '" + path + "' has schema version " +
                         std::to_string(found) + " but this fleetgw build supports at most " +
                         std::to_string(supported) +
                         "; refusing to start (was it written by a newer fleetgw? upgrade the "
                         "binary or move the file away)"),
      found_(found),
      supported_(supported) {}

int schema_version(Database& db) {
  return static_cast<int>(db.query_int64("PRAGMA user_version").value_or(0));
}

int migrate(Database& db, int target) {
  if (target < 0 || target > kSchemaVersion) {
    throw std::invalid_argument("storage: migrate target " + std::to_string(target) +
                                " outside 0.." + std::to_string(kSchemaVersion));
  }
  const int before = schema_version(db);
  if (before > kSchemaVersion) throw SchemaTooNewError(db.path(), before, kSchemaVersion);
  if (before > target) {
    throw std::invalid_argument("storage: '" + db.path() + "' is at version " +
                                std::to_string(before) + ", cannot migrate down to " +
                                std::to_string(target));
  }
  if (before == 0 && target > 0) {
    // Lets Store return evicted pages to the file system. The setting only sticks on a file
    // without pages; if something already wrote the header (e.g. journal_mode=WAL), a VACUUM of
    // the still-empty database applies it at negligible cost.
    db.exec("PRAGMA auto_vacuum = INCREMENTAL");
    if (db.query_int64("PRAGMA auto_vacuum").value_or(0) != 2) db.exec("VACUUM");
  }
  for (int version = before + 1; version <= target; ++version) {
    Transaction tx(db);
    db.exec(kSteps[static_cast<std::size_t>(version - 1)]);
    db.exec("PRAGMA user_version = " + std::to_string(version));
    tx.commit();
    spdlog::info("storage: migrated '{}' to schema version {}", db.path(), version);
  }
  return before;
}

}  // namespace fleetgw::storage
