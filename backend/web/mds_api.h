// MDS 2.0 Provider API data (Open Mobility Foundation) from the registry and the ingest's
// tables; served under /mds/ by registry_routes.cc. docs/standards.md maps every field.
//
// Contract:
//  * Only registered vehicles appear (registry_vehicles); ids: device_id is the registry's
//    UUID; trip_id, event_id and telemetry_id are name_uuid()s of the source rows, so every
//    request and instance gives the same ids.
//  * Paging: `offset`/`limit` over a stable order; *more is set when rows remain. Trips and
//    telemetry page by row, vehicles, vehicle status and events by vehicle (a page holds the
//    events of at most `limit` vehicles).
//  * Events of a window [from_us, to_us): the conditions at from_us are read from the latest
//    rows before it (an open ride, each alarm kind's latest transition, the last SOC sample of
//    the day before, removal), then the window's signals run through MdsMachine (mds_state.h).
//    Signals: rides (trip_start at started_at_us, trip_end at ended_at_us), theft-class alarms
//    (unauthorised movement, lock forced or tampered, battery removed), the outside-operating-
//    area alarm, SOC crossing low_battery_pct downwards / charged_pct upwards in telemetry,
//    connection loss (status_history when the ingest has it; else the retained offline status
//    and silence longer than offline_after_s), registry removal. An event's location is its
//    row's position, else the last one before it, else the vehicle's latest; an event with no
//    position at all is left out (MDS requires one).
//  * Trips: rides whose end lies in the window, with start/end location from the ride record
//    (else its first/last telemetry position); the route is the telemetry whose trip_ids name
//    the trip (MDS 2.0 has no route in the trip object).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>

#include "backend/common/pg.h"
#include "backend/web/registry_options.h"

namespace fleetgw::web {

struct MdsPageRequest {
  std::int64_t offset = 0;
  int limit = 1000;
};

nlohmann::json mds_vehicles(PgConnection& c, const StandardsOptions& o,
                            const std::optional<std::string>& device_id, MdsPageRequest page,
                            bool* more);
nlohmann::json mds_vehicles_status(PgConnection& c, const StandardsOptions& o,
                                   const std::optional<std::string>& device_id, std::int64_t now_us,
                                   MdsPageRequest page, bool* more);
nlohmann::json mds_trips(PgConnection& c, const StandardsOptions& o, std::int64_t from_us,
                         std::int64_t to_us, MdsPageRequest page, bool* more);
nlohmann::json mds_telemetry(PgConnection& c, const StandardsOptions& o, std::int64_t from_us,
                             std::int64_t to_us, MdsPageRequest page, bool* more);
nlohmann::json mds_events(PgConnection& c, const StandardsOptions& o, std::int64_t from_us,
                          std::int64_t to_us, MdsPageRequest page, bool* more);

}  // namespace fleetgw::web
