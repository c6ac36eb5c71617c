// Migration 9 (issue 25; migrations.h): committed_at_us of every record table defaults to the
// batch's stamp instead of a clock reading per row.
//
// Why: the stamp was a column of every row of the batch's COPY (a volatile default would have
// made PostgreSQL's COPY insert row by row instead of in multi-row batches), so the worker cut
// each message's COPY text into rows to append it: a memchr and two appends per row, a quarter
// of the worker's CPU in a profile. Now the worker sets `fleet.batch_us` once per transaction
// (set_config(..., true): gone at its end) and COPYs the messages' text as it is;
// fleet_batch_us() reads that setting, and is STABLE (current_setting and statement_timestamp
// are), so COPY keeps its multi-row inserts. Writers that do not set it (tools, tests, an
// analyst's INSERT) get the statement's start time instead, as before a clock of the database.
#include "backend/ingest/migrations.h"

namespace fleetgw::ingest {

std::string_view migration_v9_sql() {
  return R"sql(
CREATE FUNCTION fleet_batch_us() RETURNS bigint LANGUAGE sql STABLE AS
  $$ SELECT coalesce(nullif(current_setting('fleet.batch_us', true), '')::bigint,
                     (extract(epoch FROM statement_timestamp()) * 1000000)::bigint) $$;
ALTER TABLE rides ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE fault_events ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE telemetry_samples ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE pack_snapshots ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE lock_events ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE command_results ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE device_info ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE alarms ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE evictions ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE zone_events ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
ALTER TABLE campaign_samples ALTER COLUMN committed_at_us SET DEFAULT fleet_batch_us();
)sql";
}

}  // namespace fleetgw::ingest
