// The ingest's PostgreSQL schema as versioned migrations compiled into the binary.
//
// Contract:
//  * migrations() lists every migration in version order (1, 2, ...); a migration, once
//    released, is never edited: a change is a new migration.
//  * migrate(conn) brings the database to the newest version: under a session advisory lock (so
//    several workers starting together apply each migration once), each missing version runs in
//    its own transaction together with its row in `schema_migrations` (version, name,
//    applied_at). Returns the number of migrations applied (0: already current). A database
//    newer than this binary (an unknown version in schema_migrations) is refused with PgError.
//  * Throws PgError naming the failing migration.
#pragma once

#include <span>
#include <string_view>

#include "backend/common/pg.h"

namespace fleetgw::ingest {

struct Migration {
  int version;
  std::string_view name;
  std::string_view sql;
};

std::span<const Migration> migrations();

int migrate(PgConnection& conn);

// Migration 4's SQL (migrations_v4.cc): the full vehicle state and the status history.
std::string_view migration_v4_sql();

// Migration 8's SQL (migrations_v8_telemetry_fix.cc): heading and accuracy per telemetry sample.
std::string_view migration_v8_sql();

// Migration 9's SQL (migrations_v9_batch_stamp.cc): committed_at_us defaults to the batch's stamp.
std::string_view migration_v9_sql();

// Migration 10's SQL (migrations_v10_hot_updates.cc): vehicle_state's fillfactor, so a batch's
// state upserts replace each row on its own page.
std::string_view migration_v10_sql();

// Migration 11's SQL (migrations_v11_range_appends.cc): ranges appended per batch, compacted
// later; sequence_ranges a view merging both.
std::string_view migration_v11_sql();

}  // namespace fleetgw::ingest
