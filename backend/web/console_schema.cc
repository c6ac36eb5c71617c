// Console schema versions (console_schema.h). Times are µs since the Unix epoch, as in the
// ingest's tables, written by the server (not the database's clock) so tests can reason on them.
#include "backend/web/console_schema.h"

#include <string>

#include "backend/web/registry_schema.h"
#include "backend/web/revocation_schema.h"

namespace fleetgw::web {
namespace {

constexpr std::string_view kV1 = R"sql(
CREATE TABLE console_operators (
  name text PRIMARY KEY CHECK (length(name) BETWEEN 1 AND 64),
  role text NOT NULL CHECK (role IN ('viewer', 'operator', 'admin')),
  password_hash text NOT NULL, created_at_us bigint NOT NULL,
  disabled boolean NOT NULL DEFAULT false);

-- The session id itself is only in the operator's cookie: a copy of this table (a backup, a
-- replica) cannot be replayed as sessions.
CREATE TABLE console_sessions (
  id_sha256 text PRIMARY KEY,
  operator text NOT NULL REFERENCES console_operators (name) ON DELETE CASCADE,
  csrf_token text NOT NULL, address text NOT NULL, created_at_us bigint NOT NULL,
  last_seen_us bigint NOT NULL, expires_at_us bigint NOT NULL);
CREATE INDEX console_sessions_by_operator ON console_sessions (operator);

-- Failed logins per account ('account:NAME') and per client address ('address:ADDR'), shared by
-- every instance behind a load balancer.
CREATE TABLE console_login_throttle (
  key text PRIMARY KEY, failures integer NOT NULL, last_failure_us bigint NOT NULL);

CREATE TABLE console_audit (
  id bigserial PRIMARY KEY, at_us bigint NOT NULL, operator text, address text NOT NULL,
  action text NOT NULL, target text NOT NULL, result text NOT NULL,
  detail text NOT NULL DEFAULT '');
CREATE INDEX console_audit_by_time ON console_audit (at_us);

-- Keyed like the ingest's alarms rows (no foreign key: the ingest owns that table).
CREATE TABLE console_alarm_acks (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  acked_by text NOT NULL, acked_at_us bigint NOT NULL,
  PRIMARY KEY (vehicle_id, store_id, sequence));
CREATE INDEX console_alarm_acks_by_time ON console_alarm_acks (acked_at_us);
)sql";

// Version 2 (issue 28): commands the console signed and published, with the bike's result;
// alarm resolutions; API tokens for machine clients (only the SHA-256 of a token is stored).
constexpr std::string_view kV2 = R"sql(
CREATE TABLE console_commands (
  command_id text PRIMARY KEY, vehicle_id text NOT NULL, operator text NOT NULL,
  address text NOT NULL, action text NOT NULL, params text NOT NULL DEFAULT '',
  key_id text NOT NULL, delegation_serial bigint, command_sha256 text NOT NULL,
  payload_sha256 text NOT NULL, issued_at_us bigint NOT NULL, expires_at_us bigint NOT NULL,
  batch_id text, result text, reason text, result_operator text, duration_ms bigint,
  final_state text, limit_in_force text, result_at_us bigint);
CREATE INDEX console_commands_by_vehicle ON console_commands (vehicle_id, issued_at_us);
CREATE INDEX console_commands_by_result ON console_commands (result_at_us);
CREATE INDEX console_commands_by_time ON console_commands (issued_at_us);

CREATE TABLE console_alarm_resolutions (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  resolved_by text NOT NULL, resolved_at_us bigint NOT NULL, note text NOT NULL DEFAULT '',
  PRIMARY KEY (vehicle_id, store_id, sequence));
CREATE INDEX console_alarm_resolutions_by_time ON console_alarm_resolutions (resolved_at_us);

CREATE TABLE console_api_tokens (
  id bigserial PRIMARY KEY, name text NOT NULL CHECK (length(name) BETWEEN 1 AND 64),
  token_sha256 text NOT NULL UNIQUE,
  role text NOT NULL CHECK (role IN ('viewer', 'operator', 'admin')),
  created_by text NOT NULL, created_at_us bigint NOT NULL, revoked_at_us bigint,
  revoked_by text, last_used_us bigint);
)sql";

struct Version {
  int number;
  std::string_view name;
  std::string_view sql;
};
constexpr Version kVersions[] = {
    {1, "operators, sessions, login throttle, audit, alarm acknowledgements", kV1},
    {2, "console commands, alarm resolutions, API tokens", kV2},
    {3, "vehicle registry, GBFS ids, zone bundles, MDS agencies", kRegistrySchemaV3},
    {4, "revocation lists published from the console", kRevocationSchemaV4},
    {5, "vehicle reservations", kReservationSchemaV5},  // issue 27 (registry_schema.h)
};

// Any constant other than the ingest's: the lock serialises console migrations only.
constexpr std::string_view kLockKey = "7363453106150742";

}  // namespace

int migrate_console_schema(PgConnection& conn) {
  const PgParam key[] = {std::string(kLockKey)};
  conn.query("SELECT pg_advisory_lock($1::bigint)", key, "console migration lock");
  struct Unlock {
    PgConnection& c;
    std::span<const PgParam> key;
    ~Unlock() {
      try {
        if (c.ok()) c.query("SELECT pg_advisory_unlock($1::bigint)", key, "unlock");
      } catch (const PgError&) {
        // A session lock: it goes with the connection anyway.
      }
    }
  } unlock{conn, key};
  conn.exec(
      "CREATE TABLE IF NOT EXISTS console_schema_migrations (version integer PRIMARY KEY, "
      "name text NOT NULL, applied_at timestamptz NOT NULL DEFAULT now())",
      "console_schema_migrations");
  const PgResult have =
      conn.exec("SELECT coalesce(max(version), 0) FROM console_schema_migrations", "version");
  const std::int64_t current = have.int64_or_null(0, 0).value_or(0);
  const int newest = kVersions[std::size(kVersions) - 1].number;
  if (current > newest) {
    throw PgError("console schema version " + std::to_string(current) +
                      " is newer than this fleetgw serve knows (" + std::to_string(newest) +
                      "): use a newer fleetgw",
                  "");
  }
  int applied = 0;
  for (const Version& v : kVersions) {
    if (v.number <= current) continue;
    PgTransaction tx(conn);
    conn.exec(v.sql, "console schema version " + std::to_string(v.number));
    const PgParam row[] = {std::to_string(v.number), std::string(v.name)};
    conn.query("INSERT INTO console_schema_migrations (version, name) VALUES ($1, $2)", row,
               "console_schema_migrations row");
    tx.commit();
    ++applied;
  }
  return applied;
}

}  // namespace fleetgw::web
