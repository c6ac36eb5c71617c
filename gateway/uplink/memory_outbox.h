// MemoryOutbox: an in-memory OutboxSource with the exact ordering and ack semantics of the
// durable outbox (see outbox_source.h), for tests, benchmarks and the simulator.
//
// Contract: push() assigns the next sequence number (starting at 1) and returns it. All methods
// are thread-safe (a test may produce from one thread while the uplink drains on another).
// Nothing survives the object: it is not a substitute for the SQLite outbox in production.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>

#include "gateway/uplink/outbox_source.h"

namespace fleetgw::uplink {

class MemoryOutbox final : public OutboxSource {
 public:
  std::uint64_t push(int priority, std::string kind, std::int64_t created_us, std::string payload);

  using OutboxSource::peek;
  std::vector<OutgoingRecord> peek(std::size_t max_entries, std::size_t max_bytes,
                                   const std::set<std::uint64_t>& exclude,
                                   const KindSet& exclude_kinds) override;
  void ack(std::span<const std::uint64_t> seqs) override;
  OutboxStats stats() const override;

  // Number of records removed by ack() (tests check "nothing acked").
  std::uint64_t acked_records() const;

 private:
  using Key = std::pair<int, std::uint64_t>;  // (priority, seq): the peek order
  mutable std::mutex mutex_;
  std::map<Key, OutgoingRecord> entries_;
  std::map<std::uint64_t, int> priority_of_;  // seq -> priority, to find a record by seq
  std::uint64_t next_seq_ = 1;
  std::uint64_t acked_records_ = 0;
};

}  // namespace fleetgw::uplink
