// Migration 8 (issue 27; migrations.h): each telemetry sample keeps its fix's heading and
// horizontal error (Position fields 8 and 7), which MDS /telemetry reports per sample
// (`heading`, `horizontal_accuracy`). Kept apart from migrations.cc, after migrations_v4.cc's
// example. Versions 5 and 6 stay unused (migrations.cc says why).
#include "backend/ingest/migrations.h"

namespace fleetgw::ingest {

std::string_view migration_v8_sql() {
  // ADD COLUMN on the partitioned parent reaches every partition (the default one too), and
  // fleet_telemetry_partition's CREATE TABLE ... LIKE telemetry_samples copies the new columns,
  // so partitions made later match. NULL in samples written before this migration and in samples
  // whose fix had no heading or no error estimate.
  return R"sql(
ALTER TABLE telemetry_samples
  ADD COLUMN horizontal_error_dm integer, ADD COLUMN heading_ddeg integer;
)sql";
}

}  // namespace fleetgw::ingest
