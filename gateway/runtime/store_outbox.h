// StoreOutbox: the SQLite store's outbox seen through the uplink's OutboxSource interface.
//
// Contract:
//  * peek() honours the uplink's `exclude` set (its own in-flight records) and `exclude_kinds`
//    (filtered in the store's query) and returns entries in (priority, sequence) order; the first
//    entry is always returned, whatever its size. The store's own in-flight marks are not used: the
//    uplink is the single owner of "in flight".
//  * Kinds go by their stored names (proto/record_kinds.h) on both sides; an entry of a kind
//    this version does not know keeps its stored name, so the uplink refuses and drops it.
//    Payloads are passed on as stored (eviction reports are stored as fleetgw.v1.EvictionReport,
//    StoreOptions::encode_eviction_report); only a JSON eviction report of an older store is
//    converted on the way out.
//  * ack() deletes exactly the acknowledged rows. Nothing here throws (storage contract B). A
//    failed ack (full disk) is remembered: those rows are no longer offered by peek() (the
//    broker has them; re-sending them in a loop would only burn CPU and bandwidth), and their
//    deletion is retried, with the acks arriving meanwhile, when the engine's one retry schedule
//    allows (env/backoff.h: 1 s after the first failure, doubling up to 30 s, reset by a
//    success), timed on the Env's steady clock (env/env.h), never the machine's: a failing disk
//    is not asked again before then. next_retry() says when; the uplink's stage wakes for it
//    (UplinkStage), so the rows are deleted on time even when nothing else makes the uplink
//    poll. The memory for that is bounded (kMaxUndeleted); past it the oldest are forgotten
//    and simply sent again later (the backend deduplicates by sequence number). Failures show
//    in Store::health().
#pragma once

#include <optional>
#include <set>

#include "env/env.h"
#include "gateway/runtime/backoff.h"
#include "gateway/uplink/outbox_source.h"
#include "storage/store.h"

namespace fleetgw::runtime {

class StoreOutbox final : public uplink::OutboxSource {
 public:
  static constexpr std::size_t kMaxUndeleted = 100'000;

  // `env` (its steady clock times the delete retries) must outlive the outbox.
  explicit StoreOutbox(storage::Store& store, Env& env = Env::system())
      : store_(store), env_(env) {}

  using uplink::OutboxSource::peek;
  std::vector<uplink::OutgoingRecord> peek(std::size_t max_entries, std::size_t max_bytes,
                                           const std::set<std::uint64_t>& exclude,
                                           const uplink::KindSet& exclude_kinds) override;
  void ack(std::span<const std::uint64_t> seqs) override;
  uplink::OutboxStats stats() const override;
  // Acknowledged entries whose deletion failed and is still to be retried.
  std::size_t undeleted() const { return undeleted_.size(); }
  // Deletes the rows waiting for a retry if the retry is due at Env::steady_now() (peek() and
  // ack() call it too).
  void retry_deletes();
  // When the next delete retry is due (Env::steady_now() time); nullopt when none is waiting.
  std::optional<EngineTime> next_retry() const {
    if (undeleted_.empty()) return std::nullopt;
    return retry_.retry_at();
  }

 private:
  void remember(std::span<const std::uint64_t> seqs);

  // One attempt to delete `seqs`; a failure keeps them undeleted and backs the retry off.
  bool delete_rows(std::span<const std::uint64_t> seqs);

  storage::Store& store_;
  Env& env_;
  std::set<std::uint64_t> undeleted_;
  Backoff retry_;
};

// Exposed for tests: storage kind -> uplink kind (its stored name), and the legacy eviction
// JSON -> protobuf conversion.
std::string uplink_kind(storage::OutboxKind kind);
std::string eviction_payload_from_json(std::string_view json, uint64_t seq);

}  // namespace fleetgw::runtime
