// The status document the running service publishes on its status socket, the rules that decide
// whether it needs a technician's attention, and its human-readable rendering.
//
// Contract (schema 1; the runtime's provider fills it, `fleetgw status` reads it):
//   {
//     "schema": 1, "version": "0.1.0", "vehicle_id": "bike-0001", "uptime_s": 3600,
//     "bus":    {"transport": "socketcan", "interface": "can0", "state": "up",
//                "rx_frames": 0, "tx_frames": 0, "tx_failures": 0, "error_frames": 0,
//                "reopens": 0, "frame_errors": {"crc": 0, ...}, "detail": ""},
//     "nodes":  [{"name": "mc", "online": true, "last_heard_age_s": 0.2 | null,
//                 "firmware": "V1.2" | null}],          // every node the bike is expected to have
//     "faults": [{"node": "bms", "code": 12, "name": "...", "severity": "critical"}],  // active
//     "locks":  [{"kind": "seat", "state": "locked"}],
//     "vehicle": {"speed_kmh": 21.3 | null, "soc_pct": 63.0 | null, "odo_km": 880.1 | null,
//                 "assist": "eco" | null, "riding": true,     // null: not heard yet
//                 "ride": {"ride_id": "...", "start_us": 1717263000000000, "duration_s": 361.0,
//                          "moving_s": 350.2, "distance_km": 2.1, "max_speed_kmh": 24.0,
//                          "soc_start_pct": 64 | null} | null},  // optional section
//     "broker": {"enabled": true, "connected": false, "uri": "ssl://...", "last_error": "",
//                "last_connect_error": "TLS: ...", "last_connect_error_age_s": 3.2 | null,
//                "tls_failures": 2,                      // the last three: optional
//                "protocol": "5", "publish_refusals": 3, "refused_records": 1,
//                "last_publish_refusal": "0x87 Not authorized (fleet/v1/bike-0001/ride)",
//                // ^ one "<code> <name> (<topic>)" per refused kind, "; "-separated
//                "last_publish_refusal_code": 135, "last_publish_refusal_us": 0},  // optional
//     "commands": {"received": 20, "unauthenticated": 3, "busy": 84, "dropped": 5,
//                "dropped_by_reason": {"oversized": 1, "undecodable": 1, "unauthenticated": 3,
//                                      "queue_full": 0}},   // optional section (broker enabled):
//                // payloads on cmd handed to the command service (of them unauthenticated),
//                // answered busy, and dropped unanswered by class (docs/commands.md)
//     "outbox": {"depth": 12, "oldest_unsent_age_s": 120.5 | null},
//     "disk":   {"used_bytes": 1048576, "budget_bytes": 268435456},   // effective budget
//     "storage": {"failing": true, "last_error": "disk full (SQLITE_FULL)", "failed_writes": 7,
//                 "failing_since_us": 1790000000000000, "failing_for_s": 12.5 | null,
//                 "configured_budget_bytes": 268435456, "effective_budget_bytes": 104857600,
//                 "dropped_records": 0},                  // optional section
//     "gnss":   {"enabled": true, "gpsd": "localhost:2947", "connected": true, "fix": true,
//                "reason": "" | "no fix" | "gpsd unreachable" | "fix stale", "fixes": 120,
//                "lat": 52.52, "lon": 13.405, "hdop": 0.9 | null,
//                "horizontal_error_m": 17.1 | null,     // gpsd's eph (docs/location.md)
//                "satellites": 8, "last_fix_age_s": 0.4},  // optional section ([gnss] enabled)
//     "geofence": {"enabled": true, "version": 3 | null, "zones": 4, "vertices": 80,
//                "key_id": "ops", "issued_at_us": 0, "bundle_file": "/var/lib/fleetgw/zones.pb",
//                "topics": ["fleet/v1/zones"], "bundles_received": 5, "bundles_accepted": 2,
//                "bundles_refused": 3, "bundles_dropped": 0, "last_refusal_reason": "not_newer",
//                "last_refusal": "not_newer: version 1 is older than ...",
//                "last_refusal_topic": "fleet/v1/zones", "last_refusal_age_s": 2.0 | null,
//                "outside_operating_area": false}  // optional section ([geofence] enabled)
//     "revocations": {"version": 4 | null}  // the root's revocation list in force (issue 28);
//                // null: none received yet; optional section ([command.root_keys] set)
//   }
//   Ages are computed by the service on its own clock, so the client needs no clock agreement.
//   Unknown keys are ignored (newer services may add some).
//
// Attention rules (the only place they are defined): the document needs attention when
//   * a required section is missing or has the wrong type ("malformed"),
//   * the bus state is anything but "up" ("bus"),
//   * an expected node is offline ("node"),
//   * an active fault has severity "critical" ("fault"),
//   * the broker is enabled and not connected ("broker"; the detail quotes last_error, which is
//     the connect failure's reason when the service knows it, e.g. a TLS verification failure),
//   * the broker refuses publishes (MQTT 5 reason code >= 0x80; "broker", quoting
//     last_publish_refusal, e.g. "0x87 Not authorized (fleet/v1/bike-0042/ride)"),
//   * store writes are failing ("storage": reason, failed writes, for how long),
//   * the disk budget was clamped below storage.max_mb because the disk is smaller ("budget"),
//   * disk use exceeds disk_fraction of the budget ("disk"),
//   * the oldest unsent outbox record is older than outbox_max_age ("outbox"),
//   * gpsd is unreachable while [gnss] is enabled ("gnss"; no fix under a roof is not a fault
//     of the unit: it shows in the rendering and as the IoT GNSS fault, not as attention).
// The rules judge typed facts (status_health.h): the service its own, built from the live
// components (runtime::make_status_health), `fleetgw status` the document it received, read by
// health_from_json(). Evaluation never throws, whatever the JSON holds.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <string>
#include <vector>

#include "gateway/status/status_health.h"

namespace fleetgw::status {

inline constexpr int kStatusSchema = 1;

struct AttentionRules {
  double disk_fraction = 0.90;                                 // of storage.max_mb
  std::chrono::seconds outbox_max_age{std::chrono::hours(6)};  // uplink stalled this long
};

struct Attention {
  std::string rule;    // "malformed", "bus", "node", "fault", "broker", "storage", "budget",
                       // "disk", "outbox"
  std::string detail;  // one line for the technician
};

std::vector<Attention> evaluate(const Health& health, const AttentionRules& rules = {});
// A document from the socket: evaluate(health_from_json(status), rules).
std::vector<Attention> evaluate(const nlohmann::json& status, const AttentionRules& rules = {});

// Multi-line summary for a terminal, ending with either "OK" or one "ATTENTION: ..." line per
// finding.
std::string format_summary(const nlohmann::json& status, const std::vector<Attention>& findings);

}  // namespace fleetgw::status
