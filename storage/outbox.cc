// The outbox as a queue for the uplink: peek in (priority, seq) order, in-flight marks, acks.
// None of these throws (storage/store.h, contract B).
#include <spdlog/spdlog.h>

#include "storage/store_impl.h"

namespace fleetgw::storage {

std::vector<OutboxRow> Store::peek_outbox(std::size_t limit, std::size_t max_bytes) {
  return peek_outbox(limit, max_bytes, {});
}

std::vector<OutboxRow> Store::peek_outbox(std::size_t limit, std::size_t max_bytes,
                                          std::span<const OutboxKind> skip_kinds) {
  std::vector<OutboxRow> out;
  if (limit == 0) return out;
  try {
    auto& db = impl_->db;
    auto& in_flight = impl_->in_flight;
    // One cached statement per number of skipped kinds (at most one per kind): the walk stays on
    // outbox_by_priority, the skipped kinds' rows are passed over inside SQLite.
    std::string sql = "SELECT seq, priority, kind, created_us, payload, source_id FROM outbox ";
    if (!skip_kinds.empty()) {
      sql += "WHERE kind NOT IN (?";
      for (std::size_t i = 1; i < skip_kinds.size(); ++i) sql += ", ?";
      sql += ") ";
    }
    sql += "ORDER BY priority, seq LIMIT ?";
    auto st = db.cached(sql);
    int index = 1;
    for (const auto k : skip_kinds) st->bind(index++, to_string(k));
    // At most in_flight.size() rows are skipped, so this LIMIT never cuts off an eligible entry.
    st->bind(index, static_cast<std::int64_t>(limit + in_flight.size()));
    std::size_t bytes = 0;
    while (out.size() < limit && st->step()) {
      const auto seq = static_cast<std::uint64_t>(st->column_int64(0));
      if (in_flight.contains(seq)) continue;
      OutboxRow e;
      e.seq = seq;
      e.priority = static_cast<int>(st->column_int64(1));
      const std::string kind = st->column_text(2);
      if (auto k = outbox_kind_from_string(kind)) {
        e.kind = *k;
      } else {
        // Never guessed as another kind (it would go out as the wrong message): the reader
        // refuses it by name.
        impl_->log->error("storage: outbox entry {}: {}; refused", seq,
                          records::unknown_kind_message(kind));
        e.unknown_kind = kind;
      }
      e.created_us = st->column_int64(3);
      e.payload = st->column_blob(4);
      e.source_id = st->column_opt_int64(5);
      if (!out.empty() && bytes + e.payload.size() > max_bytes) break;
      bytes += e.payload.size();
      out.push_back(std::move(e));
    }
    for (const auto& e : out) in_flight.insert(e.seq);
  } catch (const std::exception& e) {
    impl_->error_log.report(std::string("storage: reading the outbox failed: ") + e.what());
    out.clear();
  }
  return out;
}

Result<std::size_t> Store::ack(std::span<const std::uint64_t> seqs) {
  if (seqs.empty()) return std::size_t{0};
  auto& db = impl_->db;
  std::size_t deleted = 0;
  if (impl_->options.read_only) return Status{StatusCode::kInvalid, "the store is open read-only"};
  Status error;
  try {
    Transaction tx(db);
    auto st = db.cached("DELETE FROM outbox WHERE seq = ?");
    for (auto seq : seqs) {
      st->bind(1, static_cast<std::int64_t>(seq));
      st->run();
      st->reset();
      deleted += static_cast<std::size_t>(db.changes());
    }
    tx.commit();
    impl_->record_success();
  } catch (const std::exception& e) {
    // Nothing deleted: the entries stay queued and are sent again (the backend deduplicates).
    error = to_status(e);
    impl_->record_failure(error, "ack");
  }
  for (auto seq : seqs) impl_->in_flight.erase(seq);
  if (!error.ok()) return error;
  return deleted;
}

void Store::release(std::span<const std::uint64_t> seqs) {
  for (auto seq : seqs) impl_->in_flight.erase(seq);
}

void Store::release_all() {
  impl_->in_flight.clear();
}

std::size_t Store::in_flight() const {
  return impl_->in_flight.size();
}

std::vector<OutboxDepth> Store::outbox_depth() {
  std::vector<OutboxDepth> out;
  try {
    auto st = impl_->db.cached(
        "SELECT priority, count(*), ifnull(sum(length(payload)), 0) FROM outbox "
        "GROUP BY priority ORDER BY priority");
    while (st->step()) {
      out.push_back({static_cast<int>(st->column_int64(0)),
                     static_cast<std::uint64_t>(st->column_int64(1)),
                     static_cast<std::uint64_t>(st->column_int64(2))});
    }
  } catch (const std::exception& e) {
    impl_->error_log.report(std::string("storage: reading the outbox depth failed: ") + e.what());
    out.clear();
  }
  return out;
}

std::uint64_t Store::visit_outbox(OutboxKind kind,
                                  const std::function<void(const OutboxRow&)>& visit) {
  std::uint64_t n = 0;
  try {
    auto st = impl_->db.cached(
        "SELECT seq, priority, created_us, payload, source_id FROM outbox WHERE kind = ? "
        "ORDER BY seq");
    st->bind(1, to_string(kind));
    OutboxRow e;
    e.kind = kind;
    while (st->step()) {
      e.seq = static_cast<std::uint64_t>(st->column_int64(0));
      e.priority = static_cast<int>(st->column_int64(1));
      e.created_us = st->column_int64(2);
      e.payload = st->column_blob(3);
      e.source_id = st->column_opt_int64(4);
      visit(e);
      ++n;
    }
    st->reset();
  } catch (const std::exception& e) {
    impl_->error_log.report(std::string("storage: reading the outbox failed: ") + e.what());
  }
  return n;
}

std::optional<std::int64_t> Store::oldest_unsent_us() {
  // Sequence order is creation order, and seq is the rowid: no scan.
  try {
    auto st = impl_->db.cached("SELECT created_us FROM outbox ORDER BY seq LIMIT 1");
    if (!st->step()) return std::nullopt;
    return st->column_int64(0);
  } catch (const std::exception& e) {
    impl_->error_log.report(std::string("storage: reading the outbox failed: ") + e.what());
    return std::nullopt;
  }
}

}  // namespace fleetgw::storage
