// The interface the uplink drains: a durable, ordered queue of records waiting to be published.
//
// Contract (implemented by the SQLite outbox in storage/, and by MemoryOutbox for tests):
//  * Every record has a unique, strictly increasing sequence number assigned when it is stored.
//  * peek() returns, without removing them, the records that should leave next: ordered by
//    priority (LOWER value first: 0 is the most urgent) and then by sequence number, skipping
//    every sequence number in `exclude` (records the uplink already holds in flight). It returns
//    at most `max_entries` records and stops before the total payload size would exceed
//    `max_bytes` -- except that the first record is always returned, whatever its size, so an
//    oversized record cannot wedge the queue. The four-argument form also skips every record
//    whose kind is in `exclude_kinds` (kinds the broker refuses and the uplink retries later:
//    the records of other kinds behind them keep flowing).
//  * ack() deletes records for good. The uplink calls it only after the broker acknowledged the
//    publish carrying exactly those records; unknown sequence numbers are ignored (a duplicate
//    ack after a reconnect is harmless).
//  * A record that is never acked stays and is returned again: after a crash, a restart or a
//    failed publish it is re-sent. Duplicates are possible, loss is not.
//  * All calls come from the uplink owner's thread (Uplink::poll); implementations need no
//    locking for the uplink's sake.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <set>
#include <span>
#include <string>
#include <vector>

namespace fleetgw::uplink {

// Record kinds understood by the uplink: the `kind` column of the outbox. Each maps to one
// Envelope body field and one topic (docs/uplink.md).
namespace kind {
inline constexpr const char* kTelemetry = "telemetry";       // payload: fleetgw.v1.TelemetrySample
inline constexpr const char* kRide = "ride";                 // payload: fleetgw.v1.RideRecord
inline constexpr const char* kFault = "fault";               // payload: fleetgw.v1.FaultEvent
inline constexpr const char* kPack = "pack";                 // payload: fleetgw.v1.PackStatistics
inline constexpr const char* kLock = "lock";                 // payload: fleetgw.v1.LockEvent
inline constexpr const char* kInfo = "info";                 // payload: fleetgw.v1.DeviceInfo
inline constexpr const char* kStatus = "status";             // payload: fleetgw.v1.Status
inline constexpr const char* kCommandResult = "cmd_result";  // payload: fleetgw.v1.CommandResult
inline constexpr const char* kEviction = "eviction";         // payload: fleetgw.v1.EvictionReport
inline constexpr const char* kAlarm = "alarm";               // payload: fleetgw.v1.Alarm
inline constexpr const char* kZone = "zone";                 // payload: fleetgw.v1.ZoneEvent
inline constexpr const char* kCampaign = "campaign";  // payload: fleetgw.v1.CampaignSamples
}  // namespace kind

// One stored record as the uplink sees it (storage::OutboxRow is the store's row type).
struct OutgoingRecord {
  std::uint64_t seq = 0;        // outbox sequence number (unique, increasing)
  int priority = 0;             // lower leaves first
  std::string kind;             // one of fleetgw::uplink::kind
  std::int64_t created_us = 0;  // when the record was made, microseconds since the Unix epoch
  std::string payload;          // the serialized body message named by `kind` (not an Envelope)

  friend bool operator==(const OutgoingRecord&, const OutgoingRecord&) = default;
};

// Queue figures for the status message and metrics.
struct OutboxStats {
  std::uint64_t depth = 0;             // records stored and not acked
  std::int64_t oldest_created_us = 0;  // created_us of the oldest stored record; 0 when empty
};

// A set of record kinds (names of fleetgw::uplink::kind); transparent, so a string_view finds.
using KindSet = std::set<std::string, std::less<>>;

class OutboxSource {
 public:
  virtual ~OutboxSource() = default;

  virtual std::vector<OutgoingRecord> peek(std::size_t max_entries, std::size_t max_bytes,
                                           const std::set<std::uint64_t>& exclude,
                                           const KindSet& exclude_kinds) = 0;
  std::vector<OutgoingRecord> peek(std::size_t max_entries, std::size_t max_bytes,
                                   const std::set<std::uint64_t>& exclude) {
    return peek(max_entries, max_bytes, exclude, KindSet{});
  }
  virtual void ack(std::span<const std::uint64_t> seqs) = 0;
  virtual OutboxStats stats() const = 0;
};

}  // namespace fleetgw::uplink
