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

#include "proto/record_kinds.h"

namespace fleetgw::uplink {

// Record kinds understood by the uplink: their stored names (the `kind` column of the outbox),
// from the record-kind table, proto/record_kinds.h (which also gives each one's Envelope body
// field, topic and payload message; docs/uplink.md).
namespace kind {
namespace detail {
constexpr const char* name(records::RecordKind k) {
  return records::stored_name(k).data();
}
}  // namespace detail
inline constexpr const char* kTelemetry = detail::name(records::RecordKind::kTelemetry);
inline constexpr const char* kRide = detail::name(records::RecordKind::kRide);
inline constexpr const char* kFault = detail::name(records::RecordKind::kFault);
inline constexpr const char* kPack = detail::name(records::RecordKind::kPack);
inline constexpr const char* kLock = detail::name(records::RecordKind::kLock);
inline constexpr const char* kInfo = detail::name(records::RecordKind::kInfo);
inline constexpr const char* kStatus = detail::name(records::RecordKind::kStatus);
inline constexpr const char* kCommandResult = detail::name(records::RecordKind::kCommandResult);
inline constexpr const char* kEviction = detail::name(records::RecordKind::kEvictionReport);
inline constexpr const char* kAlarm = detail::name(records::RecordKind::kAlarm);
inline constexpr const char* kZone = detail::name(records::RecordKind::kZone);
inline constexpr const char* kCampaign = detail::name(records::RecordKind::kCampaign);
}  // namespace kind

// One stored record as the uplink sees it (storage::OutboxRow is the store's row type).
struct OutgoingRecord {
  std::uint64_t seq = 0;        // outbox sequence number (unique, increasing)
  int priority = 0;             // lower leaves first
  std::string kind;             // a stored name (fleetgw::uplink::kind), or an unknown one
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
