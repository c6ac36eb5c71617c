// The typed rows fleetgw keeps on disk, one plain value struct per table.
//
// Contract:
// - Every timestamp is an int64 count of microseconds since the Unix epoch (field suffix _us),
//   supplied by the caller; storage never reads a clock for record data.
// - Physical quantities carry their unit in the field name. std::optional fields are stored as
//   SQL NULL when empty ("not known"), which is different from zero.
// - `id` fields are assigned by the store (SQLite rowid); values set by the caller are ignored
//   on insert and filled in when rows are read back.
// - The structs carry no behaviour; validation happens in Store::write(), which names the
//   offending batch entry and field.
// - OutboxKind / OutboxPriority: the uplink queue vocabulary. Priority 0 is the most urgent; the
//   uplink drains priority 0 completely before it sends any priority-1 entry, and so on.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "proto/record_kinds.h"

namespace fleetgw::storage {

using Bytes = std::vector<std::uint8_t>;

enum class RideState : std::uint8_t { kOpen = 0, kClosed = 1 };

struct RideRow {
  std::int64_t id = 0;
  std::string ride_id;  // unique key chosen by the ride tracker
  RideState state = RideState::kOpen;
  bool partial = false;  // the ride was reconstructed (e.g. the gateway restarted mid-ride)
  std::int64_t start_us = 0;
  std::optional<std::int64_t> end_us;  // empty while the ride is open
  double duration_s = 0;
  double moving_s = 0;
  std::optional<double> start_odo_km;
  std::optional<double> end_odo_km;
  double distance_km = 0;             // from the odometer
  double distance_integrated_km = 0;  // integrated from wheel speed
  double max_speed_kmh = 0;
  double avg_speed_kmh = 0;
  double energy_wh = 0;
  double energy_mah = 0;
  std::optional<int> soc_start_pct;
  std::optional<int> soc_end_pct;
  std::map<std::string, double> assist_time_s;  // assist mode name -> seconds (JSON text column)
  int fault_count = 0;
  // Where the ride went (schema v6), from the current GNSS fixes (gateway/domain/ride_track.h):
  // the first and latest fix, the GNSS distance and the simplified track as track_text()
  // (storage/track_text.h). Empty = no fix during the ride (NULL, never "0, 0"); a latitude
  // always comes with its longitude.
  std::optional<double> start_lat_deg;
  std::optional<double> start_lon_deg;
  std::optional<double> end_lat_deg;
  std::optional<double> end_lon_deg;
  std::optional<double> gnss_distance_m;
  std::optional<std::string> track;
  friend bool operator==(const RideRow&, const RideRow&) = default;
};

enum class FaultEventKind : std::uint8_t { kRaised = 0, kCleared = 1, kUnknown = 2 };

struct FaultEventRow {
  std::int64_t id = 0;
  int node = 0;  // MOTINOVA node number of the reporter
  int bit = 0;   // bit index in the node's fault word
  int code = 0;  // manufacturer fault code
  std::string name;
  std::string severity;
  FaultEventKind event = FaultEventKind::kUnknown;
  std::int64_t first_seen_us = 0;
  std::int64_t last_seen_us = 0;
  std::int64_t occurrences = 1;
  friend bool operator==(const FaultEventRow&, const FaultEventRow&) = default;
};

struct PackSnapshotRow {
  std::int64_t id = 0;
  std::int64_t ts_us = 0;
  std::optional<double> voltage_v;
  std::optional<double> current_a;
  std::optional<double> soc_pct;
  std::optional<double> soh_pct;
  std::optional<std::int64_t> cycles;
  std::vector<double> temps_c;  // JSON array text column
  std::optional<int> cell_min_mv;
  std::optional<int> cell_max_mv;
  std::optional<int> cell_spread_mv;
  std::optional<int> cell_min_index;
  std::optional<int> cell_max_index;
  std::string lifetime_json = "{}";  // lifetime counters, JSON object text (owned by the tracker)
  friend bool operator==(const PackSnapshotRow&, const PackSnapshotRow&) = default;
};

struct TelemetryRow {
  std::int64_t id = 0;
  std::int64_t ts_us = 0;
  std::optional<double> speed_kmh;
  std::optional<int> assist_level;
  std::optional<double> soc_pct;
  std::optional<double> voltage_v;
  std::optional<double> current_a;
  std::optional<double> motor_temp_c;
  std::optional<double> controller_temp_c;
  std::optional<double> battery_temp_c;
  std::optional<int> wheel_lock_state;    // lock node state code
  std::optional<int> battery_lock_state;  // lock node state code
  friend bool operator==(const TelemetryRow&, const TelemetryRow&) = default;
};

struct LockEventRow {
  std::int64_t id = 0;
  std::int64_t ts_us = 0;
  int lock_node = 0;
  std::string kind;  // e.g. "wheel", "battery", "cable"
  std::string old_state;
  std::string new_state;
  std::string cause;  // e.g. "command:<id>", "manual", "timeout"
  friend bool operator==(const LockEventRow&, const LockEventRow&) = default;
};

enum class AlarmTransition : std::uint8_t { kRaised = 0, kCleared = 1 };

// One operator alarm transition (schema v4). `kind` is the snake_case alarm name
// ("unauthorised_movement", "lock_forced", "lock_tamper", "low_battery", "battery_removed",
// "battery_swapped"); evidence fields that do not apply to the kind stay empty.
struct AlarmRow {
  std::int64_t id = 0;
  std::int64_t ts_us = 0;              // when the transition was decided
  std::int64_t first_evidence_us = 0;  // first evidence of the episode
  std::string kind;
  AlarmTransition transition = AlarmTransition::kRaised;
  std::optional<int> lock_node;
  std::optional<double> speed_kmh;
  std::optional<double> max_speed_kmh;
  std::optional<double> motor_rpm;
  std::optional<double> soc_pct;
  std::optional<int> threshold_pct;
  std::optional<std::int64_t> lock_fault_bits;
  std::string old_bms_serial;
  std::string new_bms_serial;
  std::string detail;
  friend bool operator==(const AlarmRow&, const AlarmRow&) = default;
};

// One geofence event (gateway/geofence/zone_engine.h ZoneEvent): a zone entered or left, or a
// lock in a no-parking zone. The position is absent when the event had none (never "0,0").
struct ZoneEventRow {
  std::int64_t id = 0;
  std::int64_t ts_us = 0;  // when the engine decided it
  std::string zone_id;
  std::string zone_name;
  std::string kind;        // "operating_area", "slow", "no_ride", "no_parking"
  std::string transition;  // "enter", "exit", "locked_in_no_parking", "lock_refused"
  std::uint64_t bundle_version = 0;
  std::optional<double> lat_deg;
  std::optional<double> lon_deg;
  std::optional<int> speed_limit_kmh;  // slow zones
  friend bool operator==(const ZoneEventRow&, const ZoneEventRow&) = default;
};

struct CommandResultRow {
  std::int64_t id = 0;
  std::string command_id;
  std::int64_t ts_us = 0;
  std::string result;  // e.g. "ok", "rejected", "failed", "expired"
  std::string reason;
  std::string final_state;
  std::int64_t duration_ms = 0;
  friend bool operator==(const CommandResultRow&, const CommandResultRow&) = default;
};

// One row of the commands journal: what the gateway has accepted and how far it got. Writing a
// journal entry also records the command id as seen until expires_at_us (duplicate delivery
// protection for QoS-1 MQTT).
struct CommandJournalRow {
  std::string command_id;
  std::int64_t received_us = 0;
  std::string state;  // e.g. "received", "executing", "done"
  std::int64_t expires_at_us = 0;
  // SHA-256 of the signed command bytes (32 raw bytes); empty when unknown (a row journaled by
  // a version before schema v3). An update with an empty digest keeps the stored one.
  std::string command_sha256{};
  friend bool operator==(const CommandJournalRow&, const CommandJournalRow&) = default;
};

// The outbox's record kinds are THE record-kind table's (proto/record_kinds.h): the `kind` TEXT
// column holds records::stored_name(kind).
using OutboxKind = records::RecordKind;

// Lower value = more urgent; the defaults of the record-kind table. Alarms share the top
// priority with command results (both are what an operator waits for; within a priority the
// sequence number orders them).
enum class OutboxPriority : std::uint8_t {
  kAlarm = records::default_priority(OutboxKind::kAlarm),
  kCommandResult = records::default_priority(OutboxKind::kCommandResult),
  kFault = records::default_priority(OutboxKind::kFault),
  kZone = records::default_priority(OutboxKind::kZone),
  kRide = records::default_priority(OutboxKind::kRide),
  kLock = records::default_priority(OutboxKind::kLock),
  kPack = records::default_priority(OutboxKind::kPack),
  kTelemetry = records::default_priority(OutboxKind::kTelemetry),
  // Below telemetry, only for OutboxKind::kCampaign (issue 29): campaign samples never hold back
  // a record of the product, and their bytes in the store are these priorities' depth. A
  // campaign of priority p (0..9, campaign.proto) is queued at kCampaign + p (6..15).
  kCampaign = records::default_priority(OutboxKind::kCampaign),
};
inline constexpr int kLowestPriority = 5;
inline constexpr int kLowestCampaignPriority = 15;  // kCampaign + 9

// records::stored_name(kind) / records::kind_from_stored_name(text).
std::string_view to_string(OutboxKind kind);
std::optional<OutboxKind> outbox_kind_from_string(std::string_view text);
std::string_view to_string(FaultEventKind kind);
std::string_view to_string(AlarmTransition transition);
std::string_view to_string(RideState state);

struct OutboxRow {
  std::uint64_t seq = 0;  // per-vehicle sequence number, never reused
  int priority = 0;
  OutboxKind kind = OutboxKind::kInfo;
  std::int64_t created_us = 0;
  Bytes payload;                          // opaque bytes produced by the gateway
  std::optional<std::int64_t> source_id;  // rowid in the kind's table, if any
  // Set when the stored kind is not one this version knows (a newer version wrote it): `kind`
  // is then meaningless and the reader refuses the entry (the uplink drops it, logged).
  std::optional<std::string> unknown_kind;
  friend bool operator==(const OutboxRow&, const OutboxRow&) = default;
};

// What one eviction pass removed to bring the database back under its disk budget. The store
// logs it, persists the per-table counters and queues it as an outbox entry of kind
// kEvictionReport whose payload StoreOptions::encode_eviction_report makes (the gateway's
// fleetgw.v1.EvictionReport wire bytes; storage does not know protobuf). Without an encoder
// (tools, storage's own tests) and in stores written before that seam, the payload is
// to_json(); write() also returns the pass.
struct EvictionPass {
  std::int64_t at_us = 0;
  std::uint64_t budget_bytes = 0;
  std::uint64_t bytes_before = 0;
  std::uint64_t bytes_after = 0;
  std::uint64_t telemetry_rows = 0;      // evicted in this pass
  std::uint64_t pack_snapshot_rows = 0;  // evicted in this pass
  std::uint64_t outbox_rows = 0;         // unsent outbox entries dropped (campaign ones included)
  std::uint64_t campaign_records = 0;    // campaign outbox entries evicted in this pass
  std::optional<std::int64_t> oldest_telemetry_kept_us;
  bool budget_exhausted = false;  // nothing evictable left; database stays above budget
  std::string to_json() const;
  friend bool operator==(const EvictionPass&, const EvictionPass&) = default;
};

}  // namespace fleetgw::storage
