// The on-disk schema of the fleetgw store and its migrations.
//
// Contract:
// - The schema version lives in `PRAGMA user_version`. 0 means an empty database.
// - Each migration is a separate step from version N-1 to N, run in its own transaction
//   together with the user_version bump, so a crash mid-migration leaves the database at N-1
//   and the step is simply repeated at the next start.
// - migrate(db, target) brings a database from its current version up to `target` (default:
//   kSchemaVersion). It never goes backwards: a database newer than `target` raises
//   SchemaTooNewError naming the file and both versions; start-up must stop (a newer binary
//   wrote data this one does not understand, and guessing would lose it).
// - Tests use migrate(db, 1) to build a genuine old-version database, then open it with the
//   current code: this is why every historical step is kept, never edited after release.
//
// History:
//   v1  base tables: rides, fault_events, pack_snapshots, telemetry, lock_events,
//       command_results, commands, seen_command_ids, meta, outbox
//   v2  eviction_counters table; outbox indexes (priority order, source lookup for eviction)
//   v3  commands.command_sha256 (nullable BLOB): the digest of the signed command bytes, so a
//       result re-published after a restart is bound to its command like a live one; NULL in
//       rows journaled before v3
//   v4  alarms table: operator alarms (unauthorised movement, lock forced/tamper, low battery,
//       battery removed/swapped), raised/cleared with their evidence; queued as outbox kind
//       "alarm" at priority 0
//   v5  zone_events table: geofence enter/exit and no-parking lock events (issue 14); queued
//       as outbox kind "zone" at priority 1
//   v6  rides: start_lat_deg, start_lon_deg, end_lat_deg, end_lon_deg, gnss_distance_m (REAL)
//       and track (TEXT: JSON array of [lon, lat], storage/track_text.h), NULL without a fix
#pragma once

#include <stdexcept>
#include <string>

#include "storage/sqlite.h"

namespace fleetgw::storage {

inline constexpr int kSchemaVersion = 7;

class SchemaTooNewError : public std::runtime_error {
 public:
  SchemaTooNewError(const std::string& path, int found, int supported);
  int found_version() const noexcept { return found_; }
  int supported_version() const noexcept { return supported_; }

 private:
  int found_;
  int supported_;
};

int schema_version(Database& db);

// Applies the migration steps current+1..target. Returns the version before migration.
int migrate(Database& db, int target = kSchemaVersion);

}  // namespace fleetgw::storage
