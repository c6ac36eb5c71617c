// The operator API's reads over the ingest's tables (docs/backend.md "Schema"; this program only
// reads them) and the console's own alarm acknowledgements, as JSON.
//
// Contract:
//  * fleet() is every vehicle known to vehicle_state or status, one object each: position
//    (degrees), mode, online (the retained status when there is one, else the state's flag),
//    SOC, range, the last telemetry speed, last seen (the later of the state's and the
//    status's arrival), current locks, active alarms, and `state`, the console's colour:
//    "alarm" (an active alarm), "offline", "low_battery" (SOC < 20 %), "riding", "parked".
//    An alarm is active while the latest row of its (kind, lock kind) on that vehicle is
//    ALARM_TRANSITION_RAISED.
//  * vehicle() is one vehicle's fleet object plus its status, recent rides (each with its
//    track, at most 500 points), faults, alarms and commands (each at most 50, newest first);
//    nullopt when the vehicle is unknown.
//  * alarms() is the latest `limit` alarm rows, newest first, each with `active` and its
//    acknowledgement (who, when) if any.
//  * Alarm ids are "<hex vehicle id>.<hex store id>.<sequence>": opaque to clients, URL-safe
//    whatever bytes the ids hold. parse_alarm_id() is nullopt for anything else.
//  * ack_alarm(): Acked (recorded now), AlreadyAcked (the first acknowledgement stands) or
//    NoSuchAlarm.
//  * Every string from the database is untrusted: it goes out only as a JSON string (escaped by
//    the serialiser; invalid UTF-8 becomes U+FFFD), and every query takes values as parameters.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "backend/common/pg.h"

namespace fleetgw::web {

struct AlarmKey {
  std::string vehicle_id;
  std::string store_id;
  std::int64_t sequence = 0;
};
std::string alarm_id(const AlarmKey& k);
std::optional<AlarmKey> parse_alarm_id(std::string_view id);

nlohmann::json fleet(PgConnection& c);
// The fleet for the console's map and list (GET /api/fleet?view=compact): {"fields": [names],
// "vehicles": [[values in the order of fields], ...]}, the same vehicles and values as fleet()
// (locks as [kind, name] pairs, alarms as their active and unacknowledged counts).
inline constexpr std::string_view kCompactFleetFields[] = {
    "id", "lat", "lon", "state", "soc_pct", "speed_kmh", "last_seen_us", "locks",
    "alarms_active", "alarms_unacked"};
nlohmann::json fleet_compact(PgConnection& c);
std::optional<nlohmann::json> vehicle(PgConnection& c, std::string_view vehicle_id);
nlohmann::json alarms(PgConnection& c, int limit);

enum class AckResult { Acked, AlreadyAcked, NoSuchAlarm };
AckResult ack_alarm(PgConnection& c, const AlarmKey& key, std::string_view operator_name,
                    std::int64_t now_us);

// JSON text for a response: never throws on invalid UTF-8 (replaced).
std::string to_json_text(const nlohmann::json& j);

}  // namespace fleetgw::web
