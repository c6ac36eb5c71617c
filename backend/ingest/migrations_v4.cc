// Migration 4 (migrations.h): the fleet state a console and the city's feeds read (issue 25,
// for issue 28's console and the GBFS/MDS feeds): everything VehicleState carries, and every
// connection change instead of only the latest status. Kept apart from migrations.cc (that file
// stays under the project's 600 lines; later migrations may follow this one's example).
#include "backend/ingest/migrations.h"

namespace fleetgw::ingest {

std::string_view migration_v4_sql() {
  return R"sql(
-- The rest of VehicleState (NULL in rows written before this migration, until the vehicle's
-- next state): locks and faults as JSON arrays of objects, alarms as enum names.
ALTER TABLE vehicle_state
  ADD COLUMN locks jsonb, ADD COLUMN faults jsonb, ADD COLUMN active_alarms text[],
  ADD COLUMN speed_limit_dkmh integer, ADD COLUMN assist integer, ADD COLUMN assist_name text,
  ADD COLUMN bus_state text, ADD COLUMN position_fixed_at_us bigint,
  ADD COLUMN horizontal_error_dm integer, ADD COLUMN heading_ddeg integer;

-- Every change of a vehicle's connection (online, offline, last will), as its statuses told it:
-- a row when a status's (online, last_will) differs from the vehicle's previous row. A last
-- will is published by the broker long after the gateway made it (at connect), so its time is
-- when it was received; other statuses carry the gateway's own clock.
CREATE TABLE status_history (
  id bigserial PRIMARY KEY, vehicle_id text NOT NULL, created_at_us bigint NOT NULL,
  online text NOT NULL, last_will boolean NOT NULL, connection text NOT NULL,
  connected_at_us bigint, received_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  event_at_us bigint GENERATED ALWAYS AS
    (CASE WHEN last_will THEN received_at_us ELSE created_at_us END) STORED,
  UNIQUE (vehicle_id, created_at_us, online, last_will));
CREATE INDEX status_history_latest ON status_history (vehicle_id, id DESC);
CREATE INDEX status_history_by_time ON status_history (event_at_us);
-- Each vehicle's current status starts its history (so its next change is seen as one).
INSERT INTO status_history (vehicle_id, created_at_us, online, last_will, connection)
  SELECT vehicle_id, created_at_us, online, last_will, connection FROM status;
)sql";
}

}  // namespace fleetgw::ingest
