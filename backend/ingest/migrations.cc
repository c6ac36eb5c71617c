// The ingest schema (migrations.h). Conventions, as on the wire (docs/uplink.md "Units"):
// integers in the unit their name ends with, times in µs since the Unix epoch (`_us`), so a row
// and its Envelope agree exactly. Every record table is keyed by (vehicle_id, store_id, sequence)
// (docs/backend.md explains the key) and carries created_at_us (the gateway's clock) and
// committed_at_us (the database's clock at insert, for the delivery delay).
#include "backend/ingest/migrations.h"

#include <string>

#include "backend/ingest/campaign_rows.h"

namespace fleetgw::ingest {
namespace {

// v1: the record tables, latest-state tables, gap tracking and rejected messages.
constexpr std::string_view kV1 = R"sql(
CREATE FUNCTION fleet_now_us() RETURNS bigint LANGUAGE sql VOLATILE AS
  $$ SELECT (extract(epoch FROM clock_timestamp()) * 1000000)::bigint $$;

CREATE TABLE rides (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  ride_id text NOT NULL, started_at_us bigint, ended_at_us bigint, duration_ms bigint,
  moving_time_ms bigint, start_odo_m bigint, end_odo_m bigint, distance_odo_m bigint,
  distance_integrated_m bigint, distance_gnss_m bigint, max_speed_dkmh integer,
  avg_speed_dkmh integer, energy_mwh bigint, energy_mah bigint, soc_start_pct integer,
  soc_end_pct integer, fault_count integer, partial boolean, partial_reason text,
  start_lat_e7 integer, start_lon_e7 integer, end_lat_e7 integer, end_lon_e7 integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));
CREATE INDEX rides_by_start ON rides (started_at_us);

CREATE TABLE fault_events (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  node text NOT NULL, bit integer NOT NULL, code integer, name text NOT NULL,
  severity text NOT NULL, kind text NOT NULL, first_seen_us bigint, last_seen_us bigint,
  occurrences integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));

CREATE TABLE telemetry_samples (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  sampled_at_us bigint NOT NULL,
  speed_dkmh integer, motor_rpm integer, power_w integer, voltage_mv integer,
  current_ma integer, cadence_rpm integer, torque_dnm integer, assist integer,
  soc_pct integer, range_m integer, odo_m bigint, trip_m bigint, pcb_temp_c integer,
  motor_temp_c integer, mcu_temp_c integer, remaining_mah integer, full_mah integer,
  pack_temp_c integer, lat_e7 integer, lon_e7 integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));
CREATE INDEX telemetry_by_time ON telemetry_samples (vehicle_id, sampled_at_us);

CREATE TABLE pack_snapshots (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  pack_serial text NOT NULL, measured_at_us bigint, voltage_mv integer,
  discharge_current_ma integer, soc_pct integer, soh_pct integer, remaining_mah integer,
  full_mah integer, cycles integer, temp_c integer[], cells_mv integer[], cell_min_mv integer,
  cell_max_mv integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));

CREATE TABLE lock_events (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  node text NOT NULL, lock_kind text NOT NULL, previous_state text NOT NULL,
  state text NOT NULL, previous_state_name text NOT NULL, state_name text NOT NULL,
  source text NOT NULL, at_us bigint, command_id text NOT NULL, lat_e7 integer, lon_e7 integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));

-- Results published straight from the command path (not stored on the gateway) carry
-- sequence 0: for them the command id completes the key.
CREATE TABLE command_results (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  command_id text NOT NULL, result text NOT NULL, reason text NOT NULL,
  final_lock_state_name text NOT NULL, duration_ms bigint, stored boolean NOT NULL,
  mc_action text NOT NULL, command_sha256 bytea,
  PRIMARY KEY (vehicle_id, store_id, sequence, command_id));

-- Commands as operators published them on <prefix>/<vehicle>/cmd, as seen on the wire: the
-- gateway verifies signatures, the ingest only records (its rows are not proof of anything).
CREATE TABLE commands (
  command_id text PRIMARY KEY, vehicle_id text NOT NULL, key_id text NOT NULL,
  issued_at_us bigint, expires_at_us bigint, action text NOT NULL, target text NOT NULL,
  received_at_us bigint NOT NULL DEFAULT fleet_now_us());

CREATE TABLE device_info (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL, nodes jsonb NOT NULL,
  PRIMARY KEY (vehicle_id, store_id, sequence));

CREATE TABLE alarms (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  kind text NOT NULL, transition text NOT NULL, at_us bigint, first_evidence_us bigint,
  speed_dkmh integer, soc_pct integer, lock_kind text NOT NULL, detail text NOT NULL,
  PRIMARY KEY (vehicle_id, store_id, sequence));

CREATE TABLE evictions (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  evicted_records bigint NOT NULL, first_sequence bigint NOT NULL, last_sequence bigint NOT NULL,
  oldest_created_at_us bigint, newest_created_at_us bigint, by_kind jsonb NOT NULL,
  reason text NOT NULL,
  PRIMARY KEY (vehicle_id, store_id, sequence));

-- Latest retained status and state per vehicle (not records: sequence 0 on the wire).
CREATE TABLE status (
  vehicle_id text PRIMARY KEY, received_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  created_at_us bigint NOT NULL, online text NOT NULL, connection text NOT NULL,
  outbox_depth bigint, bus_state text NOT NULL, firmware_version text NOT NULL,
  last_will boolean NOT NULL, attention text[] NOT NULL);

CREATE TABLE vehicle_state (
  vehicle_id text PRIMARY KEY, received_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  updated_at_us bigint NOT NULL, online boolean NOT NULL, mode text NOT NULL,
  soc_pct integer, range_m integer, odo_m bigint, lat_e7 integer, lon_e7 integer);

-- Sequence numbers accounted for, per (vehicle, store), as merged closed ranges: received
-- records, and ranges an EvictionReport says the gateway dropped. A hole between two ranges
-- (or before the first) is a gap: records not (yet) received. See the view sequence_gaps.
CREATE TABLE sequence_ranges (
  vehicle_id text NOT NULL, store_id text NOT NULL, first_seq bigint NOT NULL,
  last_seq bigint NOT NULL, CHECK (first_seq >= 1 AND last_seq >= first_seq),
  PRIMARY KEY (vehicle_id, store_id, first_seq));

CREATE VIEW sequence_gaps AS
  SELECT vehicle_id, store_id, prev_last + 1 AS first_missing, first_seq - 1 AS last_missing
  FROM (SELECT vehicle_id, store_id, first_seq,
               coalesce(lag(last_seq) OVER w, 0) AS prev_last
        FROM sequence_ranges
        WINDOW w AS (PARTITION BY vehicle_id, store_id ORDER BY first_seq)) r
  WHERE first_seq > prev_last + 1;

CREATE TABLE rejected_messages (
  id bigserial PRIMARY KEY, received_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  topic text NOT NULL, reason text NOT NULL, payload_bytes integer NOT NULL);

-- Latest firmware per vehicle and node, for fault rates by firmware.
CREATE VIEW vehicle_firmware AS
  SELECT DISTINCT ON (d.vehicle_id, n.node) d.vehicle_id, n.node, n.model, n.fw_version,
         d.created_at_us
  FROM device_info d,
       jsonb_to_recordset(d.nodes) AS n(node text, model text, serial text, hw_version text,
                                        fw_version text)
  ORDER BY d.vehicle_id, n.node, d.created_at_us DESC;
)sql";

// v2 (schema v1.4 on the wire): zone events (Envelope field 21, topic .../zone) as a record
// table, and the Status publish-refusal fields 16-19 as status columns (NULL only in rows
// written before v2; a gateway older than v1.4 sends none, stored as proto3's 0 and "").
constexpr std::string_view kV2 = R"sql(
CREATE TABLE zone_events (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  zone_id text NOT NULL, zone_name text NOT NULL, kind text NOT NULL, transition text NOT NULL,
  at_us bigint, lat_e7 integer, lon_e7 integer, bundle_version bigint, speed_limit_kmh integer,
  PRIMARY KEY (vehicle_id, store_id, sequence));
CREATE INDEX zone_events_by_zone ON zone_events (zone_id, at_us);

ALTER TABLE status ADD COLUMN publish_refusals bigint,
  ADD COLUMN last_publish_refusal text, ADD COLUMN last_publish_refusal_code integer,
  ADD COLUMN last_publish_refusal_at_us bigint;
)sql";

// v3 (issue 25): telemetry partitioned by day of sampled_at_us (declarative partitioning), with
// a default partition for samples outside any day partition (a gateway without a clock stamps
// 1970) and functions the worker calls to create partitions ahead and drop old ones
// (--partition-days-ahead, --retention-days). The key gains sampled_at_us (a partitioned
// table's unique key must hold the partition key): a redelivered sample repeats its
// sampled_at_us, so it still conflicts. Every row of the old table moves over. Plus the indexes
// the analyst queries of docs/backend.md use.
constexpr std::string_view kV3 = R"sql(
ALTER TABLE telemetry_samples RENAME TO telemetry_samples_v2;
ALTER INDEX telemetry_samples_pkey RENAME TO telemetry_samples_v2_pkey;
ALTER INDEX telemetry_by_time RENAME TO telemetry_v2_by_time;

CREATE TABLE telemetry_samples (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  sampled_at_us bigint NOT NULL,
  speed_dkmh integer, motor_rpm integer, power_w integer, voltage_mv integer,
  current_ma integer, cadence_rpm integer, torque_dnm integer, assist integer,
  soc_pct integer, range_m integer, odo_m bigint, trip_m bigint, pcb_temp_c integer,
  motor_temp_c integer, mcu_temp_c integer, remaining_mah integer, full_mah integer,
  pack_temp_c integer, lat_e7 integer, lon_e7 integer,
  PRIMARY KEY (vehicle_id, store_id, sequence, sampled_at_us)) PARTITION BY RANGE (sampled_at_us);
CREATE INDEX telemetry_by_time ON telemetry_samples (vehicle_id, sampled_at_us);
CREATE TABLE telemetry_samples_default PARTITION OF telemetry_samples DEFAULT;

-- The partition of the UTC day starting at day_us (telemetry_samples_pYYYYMMDD), made once;
-- rows of that day already in the default partition move into it.
CREATE FUNCTION fleet_telemetry_partition(day_us bigint) RETURNS void LANGUAGE plpgsql AS $$
DECLARE
  name text := 'telemetry_samples_p' ||
               to_char(to_timestamp(day_us / 1e6) AT TIME ZONE 'UTC', 'YYYYMMDD');
  day_end bigint := day_us + 86400000000;
BEGIN
  IF to_regclass(name) IS NOT NULL THEN RETURN; END IF;
  EXECUTE format('CREATE TABLE %I (LIKE telemetry_samples INCLUDING DEFAULTS)', name);
  EXECUTE format('WITH moved AS (DELETE FROM telemetry_samples_default WHERE sampled_at_us >= %s '
                 'AND sampled_at_us < %s RETURNING *) INSERT INTO %I SELECT * FROM moved',
                 day_us, day_end, name);
  EXECUTE format('ALTER TABLE telemetry_samples ATTACH PARTITION %I FOR VALUES FROM (%s) TO (%s)',
                 name, day_us, day_end);
END $$;

-- Partitions from yesterday to days_ahead days ahead; with retention_days > 0, day partitions
-- that ended more than retention_days ago are dropped. Returns the number dropped. Workers
-- call it at start and hourly; the lock makes concurrent calls take turns.
CREATE FUNCTION fleet_maintain_telemetry_partitions(days_ahead int, retention_days int)
RETURNS int LANGUAGE plpgsql AS $$
DECLARE
  today bigint := (floor(fleet_now_us() / 86400000000.0) * 86400000000)::bigint;
  part record;
  dropped int := 0;
BEGIN
  PERFORM pg_advisory_xact_lock(7363453106150742);
  FOR i IN -1..days_ahead LOOP
    PERFORM fleet_telemetry_partition(today + i * 86400000000);
  END LOOP;
  IF retention_days > 0 THEN
    FOR part IN SELECT c.relname FROM pg_inherits h JOIN pg_class c ON c.oid = h.inhrelid
                WHERE h.inhparent = 'telemetry_samples'::regclass
                  AND c.relname ~ '^telemetry_samples_p[0-9]{8}$' LOOP
      IF to_date(substr(part.relname, 20), 'YYYYMMDD') + 1 <=
         (now() AT TIME ZONE 'UTC')::date - retention_days THEN
        EXECUTE format('DROP TABLE %I', part.relname);
        dropped := dropped + 1;
      END IF;
    END LOOP;
  END IF;
  RETURN dropped;
END $$;

-- Every row of the old table is kept: the days it holds (years 2000-2099; others go to the
-- default partition) get their partitions first.
DO $$
DECLARE d bigint;
BEGIN
  FOR d IN SELECT DISTINCT (floor(sampled_at_us / 86400000000.0) * 86400000000)::bigint
           FROM telemetry_samples_v2
           WHERE sampled_at_us >= 946684800000000 AND sampled_at_us < 4102444800000000 LOOP
    PERFORM fleet_telemetry_partition(d);
  END LOOP;
END $$;
INSERT INTO telemetry_samples SELECT * FROM telemetry_samples_v2;
DROP TABLE telemetry_samples_v2;

-- Fault rates by firmware: raised faults per vehicle; the latest device info per vehicle.
CREATE INDEX fault_events_by_kind ON fault_events (kind, vehicle_id);
CREATE INDEX device_info_latest ON device_info (vehicle_id, created_at_us DESC);
)sql";

// Versions 5 and 6 were never used (reserved for work that went into the console's own schema);
// a database is migrated past every version above its highest, so the next one is 8, never 5.
const Migration kMigrations[] = {
    {1, "records, latest state, sequence ranges, rejected messages", kV1},
    {2, "zone events, status publish refusals", kV2},
    {3, "telemetry partitioned by day, analyst indexes", kV3},
    {4, "full vehicle state, status history", migration_v4_sql()},
    {7, "campaign samples", migration_v7_sql()},  // issue 29 (migrations_v7_campaigns.cc)
    {8, "telemetry heading and accuracy", migration_v8_sql()},  // issue 27 (migrations_v8_*.cc)
    {9, "committed_at_us from the batch's stamp", migration_v9_sql()},  // issue 25 (v9_*.cc)
    {10, "room on vehicle_state pages for in-place updates", migration_v10_sql()},  // issue 25
    {11, "sequence ranges appended per batch, compacted later", migration_v11_sql()},  // issue 25
};

// Any constant: the lock only serialises ingest workers migrating the same database.
constexpr std::string_view kLockKey = "7363453106150741";

}  // namespace

std::span<const Migration> migrations() {
  return kMigrations;
}

int migrate(PgConnection& conn) {
  const PgParam key[] = {std::string(kLockKey)};
  conn.exec_params("SELECT pg_advisory_lock($1::bigint)", key, "migration lock");
  struct Unlock {
    PgConnection& c;
    const PgParam* key;
    ~Unlock() {
      if (c.ok()) {
        try {
          c.exec_params("SELECT pg_advisory_unlock($1::bigint)", std::span(key, 1),
                        "migration unlock");
        } catch (const PgError&) {
          // The lock is a session lock: it goes with the connection anyway.
        }
      }
    }
  } unlock{conn, key};

  conn.exec(
      "CREATE TABLE IF NOT EXISTS schema_migrations (version integer PRIMARY KEY, "
      "name text NOT NULL, applied_at timestamptz NOT NULL DEFAULT now())",
      "schema_migrations");
  const PgResult have =
      conn.exec("SELECT coalesce(max(version), 0) FROM schema_migrations", "schema version");
  const std::int64_t current = have.int64(0, 0);
  const int newest = migrations().back().version;
  if (current > newest) {
    throw PgError("database schema version " + std::to_string(current) +
                      " is newer than this fleetgw ingest knows (" + std::to_string(newest) +
                      "): use a newer fleetgw",
                  "");
  }
  int applied = 0;
  for (const Migration& m : migrations()) {
    if (m.version <= current) continue;
    PgTransaction tx(conn);
    conn.exec(m.sql, "migration " + std::to_string(m.version) + " (" + std::string(m.name) + ")");
    const PgParam row[] = {std::to_string(m.version), std::string(m.name)};
    conn.exec_params("INSERT INTO schema_migrations (version, name) VALUES ($1, $2)", row,
                     "schema_migrations row");
    tx.commit();
    ++applied;
  }
  return applied;
}

}  // namespace fleetgw::ingest
