// Vehicle reservations (issue 27): an operator holds a registered vehicle for a rider for a
// bounded time. GBFS vehicle_status shows it `is_reserved` (still listed); MDS puts it in the
// `reserved` state with reservation_start / reservation_stop events (mds_signals.cc).
//
// Contract:
//  * Console schema version 5 (kReservationSchemaV5 in registry_schema.h): one row per
//    reservation, never deleted (MDS events/historical reads past ones). A reservation is in
//    force at t when started_at_us <= t < ends_at_us (ends_at_us: the earlier of its expiry and
//    its cancellation) and no ride of the vehicle started at or after started_at_us and before
//    t (a trip consumes the reservation: reserved -> on_trip).
//  * reserve_vehicle(): the vehicle must be registered and not removed (NotFound), not riding
//    now and not reserved already (Conflict); expires_in_s in 60..7200 (std::invalid_argument
//    otherwise). Serialised per vehicle by a row lock on registry_vehicles, so two operators
//    cannot both reserve one bike.
//  * cancel_reservation(): ends the vehicle's reservation in force now (ended_at_us = now,
//    reason "cancelled"); nullopt when there is none.
//  * Routes (mount_reservation_routes, on `fleetgw serve`):
//      POST   /api/vehicles/{id}/reservation  {"expires_in_s": N} (default 900)
//             operator role, CSRF, audited "vehicle_reserve"; 201 with the reservation,
//             400 (bad body, naming the field), 404 (not registered), 409 (reserved or riding).
//      DELETE /api/vehicles/{id}/reservation  operator role, CSRF, audited
//             "vehicle_reservation_cancel"; 200 with the ended reservation, 404 when none.
//      GET    /api/reservations  viewer role; {"reservations": [...]}, those in force now.
//    A reservation as JSON: reservation_id, vehicle_id, reserved_by, started_at_us,
//    expires_at_us, ended_at_us (null while in force), end_reason.
#pragma once

#include <httplib.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/registry_routes.h"
#include "backend/web/registry_schema.h"

namespace fleetgw::web {

// SQL condition: reservation `rsv` (alias of vehicle_reservations) in force at the bigint
// expression `at` (see the contract). Used by the GBFS and MDS queries so that both read
// reservations alike.
inline constexpr std::string_view kReservationInForce =
    "rsv.started_at_us <= {at} AND rsv.ends_at_us > {at} AND NOT EXISTS (SELECT 1 FROM rides rr "
    "WHERE rr.vehicle_id = rsv.vehicle_id AND rr.started_at_us >= rsv.started_at_us AND "
    "rr.started_at_us < {at})";
std::string reservation_in_force_sql(std::string_view at_expression);

enum class ReserveOutcome { Reserved, NotFound, Conflict };

struct ReserveResult {
  ReserveOutcome outcome = ReserveOutcome::Reserved;
  nlohmann::json reservation;  // Reserved: the new one; Conflict: the reason ({"error": ...})
};

ReserveResult reserve_vehicle(PgConnection& c, std::string_view vehicle_id,
                              std::string_view operator_name, std::int64_t expires_in_s,
                              std::int64_t now_us);
std::optional<nlohmann::json> cancel_reservation(PgConnection& c, std::string_view vehicle_id,
                                                 std::int64_t now_us);
std::optional<nlohmann::json> reservation_in_force(PgConnection& c, std::string_view vehicle_id,
                                                   std::int64_t now_us);

nlohmann::json reservations_in_force(PgConnection& c, std::int64_t now_us);

void mount_reservation_routes(httplib::Server& server, PgPool& pool, Auth& auth,
                              AuthoriseFn authorise);

}  // namespace fleetgw::web
