// THE table of record kinds: every kind of record the gateway queues in its outbox and
// publishes, with every name and number other parts of the system know it by.
//
// Why one table: storage (the outbox's `kind` TEXT column), the uplink (Envelope body field and
// topic), the backend ingest (destination table) and the priorities used to be five hand-kept
// lists; adding a kind touched ten places and the same concept had up to five spellings.
// Everything below derives from kRecordKinds: storage::OutboxKind is RecordKind, the uplink's
// routes and topics are looked up here, the ingest picks its table by `ingest_table`.
//
// Contract:
//  * No protobuf types here: storage/ (which must not know protobuf) and backend/ (which depends
//    on proto/ only) both include this header. Field numbers and message names are plain values;
//    tests/uplink/test_record_kinds.cc checks them against fleetgw.v1.Envelope's descriptor.
//  * stored_name is written into existing SQLite stores: never change one (a store written by an
//    older version must still read). topic_leaf is a wire contract with deployed bikes and the
//    shipped broker ACL (deploy/mosquitto/acl): never change one either.
//  * kRecordKinds[i].kind == RecordKind(i): the table is indexed by the enum.
//  * Adding a kind: a RecordKind value and a row here, its body in envelope.proto, its producer
//    (gateway/domain or wherever it is born), its topic entry in gateway/uplink/topics.h
//    (kTopicTable; the ACL test fails until deploy/mosquitto/acl grants it) and its ingest table
//    (backend/ingest: migration + row function). docs/data-model.md, "Adding a record kind".
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fleetgw::records {

enum class RecordKind : std::uint8_t {
  kTelemetry,
  kRide,
  kFault,
  kPack,
  kLock,
  kInfo,
  kStatus,
  kCommandResult,
  kEvictionReport,
  kAlarm,
  kZone,
  kCampaign,  // collection campaign samples (issue 29): no table row, lowest priorities
};

struct RecordKindSpec {
  RecordKind kind;
  std::string_view stored_name;     // outbox.kind TEXT in SQLite; also the uplink's name
  std::string_view topic_leaf;      // <prefix>/<vehicle_id>/<leaf> it is published on
  int envelope_field;               // fleetgw.v1.Envelope body field number
  std::string_view body_message;    // full name of that field's message type
  std::string_view stored_message;  // what the outbox payload holds (a sample for telemetry)
  std::string_view ingest_table;    // the backend's PostgreSQL table for it
  int default_priority;             // outbox priority; lower leaves first
};

// Priorities (0 is the most urgent; the uplink drains a priority completely before the next).
// Alarms share the top with command results: both are what an operator waits for.
inline constexpr int kCampaignBasePriority = 6;  // + the campaign's own 0..9 (campaign.proto)

inline constexpr std::array<RecordKindSpec, 12> kRecordKinds{{
    {RecordKind::kTelemetry, "telemetry", "telemetry", 10, "fleetgw.v1.TelemetryBatch",
     "fleetgw.v1.TelemetrySample", "telemetry_samples", 5},
    {RecordKind::kRide, "ride", "ride", 11, "fleetgw.v1.RideRecord", "fleetgw.v1.RideRecord",
     "rides", 2},
    {RecordKind::kFault, "fault", "fault", 12, "fleetgw.v1.FaultEvent", "fleetgw.v1.FaultEvent",
     "fault_events", 1},
    {RecordKind::kPack, "pack", "pack", 13, "fleetgw.v1.PackStatistics",
     "fleetgw.v1.PackStatistics", "pack_snapshots", 4},
    {RecordKind::kLock, "lock", "lock", 14, "fleetgw.v1.LockEvent", "fleetgw.v1.LockEvent",
     "lock_events", 3},
    {RecordKind::kInfo, "info", "info", 15, "fleetgw.v1.DeviceInfo", "fleetgw.v1.DeviceInfo",
     "device_info", 4},
    // Status is published by the uplink itself (retained), not queued; listed for its topic,
    // field and table.
    {RecordKind::kStatus, "status", "status", 16, "fleetgw.v1.Status", "fleetgw.v1.Status",
     "status", 0},
    // The topic keeps its historic "cmd/result" (bikes in the field and the shipped ACL use it);
    // everywhere else the concept is "command_result" (docs/data-model.md).
    {RecordKind::kCommandResult, "command_result", "cmd/result", 17, "fleetgw.v1.CommandResult",
     "fleetgw.v1.CommandResult", "command_results", 0},
    {RecordKind::kEvictionReport, "eviction_report", "eviction", 18, "fleetgw.v1.EvictionReport",
     "fleetgw.v1.EvictionReport", "evictions", 1},
    {RecordKind::kAlarm, "alarm", "alarm", 19, "fleetgw.v1.Alarm", "fleetgw.v1.Alarm", "alarms", 0},
    {RecordKind::kZone, "zone", "zone", 21, "fleetgw.v1.ZoneEvent", "fleetgw.v1.ZoneEvent",
     "zone_events", 1},
    {RecordKind::kCampaign, "campaign", "campaign", 22, "fleetgw.v1.CampaignSamples",
     "fleetgw.v1.CampaignSamples", "campaign_samples", kCampaignBasePriority},
}};

constexpr const RecordKindSpec& spec(RecordKind kind) {
  return kRecordKinds[static_cast<std::size_t>(kind)];
}
// "invalid" for a value outside the enum (a cast gone wrong), never out of bounds.
constexpr std::string_view stored_name(RecordKind kind) {
  return static_cast<std::size_t>(kind) < kRecordKinds.size() ? spec(kind).stored_name
                                                              : std::string_view("invalid");
}
constexpr int default_priority(RecordKind kind) {
  return spec(kind).default_priority;
}

// The kind stored under `name` (outbox.kind); nullopt for a name this version does not know.
std::optional<RecordKind> kind_from_stored_name(std::string_view name);
// The kind carried in Envelope body field `field`; nullptr for none (e.g. the retained
// VehicleState, which is not a record, or a field newer than this build).
const RecordKindSpec* find_by_envelope_field(int field);
// The kind published on `leaf`; nullptr for none.
const RecordKindSpec* find_by_topic_leaf(std::string_view leaf);
// "unknown record kind 'x' (this version knows: telemetry, ride, ...)": why a stored name is
// refused, for logs.
std::string unknown_kind_message(std::string_view name);

}  // namespace fleetgw::records
