#include "gateway/uplink/memory_outbox.h"

#include <algorithm>

namespace fleetgw::uplink {

std::uint64_t MemoryOutbox::push(int priority, std::string kind, std::int64_t created_us,
                                 std::string payload) {
  std::lock_guard lock(mutex_);
  const std::uint64_t seq = next_seq_++;
  entries_.emplace(Key{priority, seq},
                   OutgoingRecord{seq, priority, std::move(kind), created_us, std::move(payload)});
  priority_of_.emplace(seq, priority);
  return seq;
}

std::vector<OutgoingRecord> MemoryOutbox::peek(std::size_t max_entries, std::size_t max_bytes,
                                               const std::set<std::uint64_t>& exclude,
                                               const KindSet& exclude_kinds) {
  std::lock_guard lock(mutex_);
  std::vector<OutgoingRecord> out;
  std::size_t bytes = 0;
  for (const auto& [key, entry] : entries_) {
    if (out.size() >= max_entries) break;
    if (exclude.contains(entry.seq) || exclude_kinds.contains(entry.kind)) continue;
    if (!out.empty() && bytes + entry.payload.size() > max_bytes) break;
    bytes += entry.payload.size();
    out.push_back(entry);
  }
  return out;
}

void MemoryOutbox::ack(std::span<const std::uint64_t> seqs) {
  std::lock_guard lock(mutex_);
  for (const std::uint64_t seq : seqs) {
    const auto it = priority_of_.find(seq);
    if (it == priority_of_.end()) continue;
    entries_.erase(Key{it->second, seq});
    priority_of_.erase(it);
    ++acked_records_;
  }
}

OutboxStats MemoryOutbox::stats() const {
  std::lock_guard lock(mutex_);
  OutboxStats s;
  s.depth = entries_.size();
  for (const auto& [key, entry] : entries_) {
    if (s.oldest_created_us == 0 || entry.created_us < s.oldest_created_us) {
      s.oldest_created_us = entry.created_us;
    }
  }
  return s;
}

std::uint64_t MemoryOutbox::acked_records() const {
  std::lock_guard lock(mutex_);
  return acked_records_;
}

}  // namespace fleetgw::uplink
