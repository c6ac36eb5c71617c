// PostgreSQL writes of the ingest (ingest_store.h).
#include "gateway/ingest/ingest_store.h"

#include <algorithm>
#include <span>

#include "gateway/common/untrusted_text.h"
#include "gateway/ingest/migrations.h"

namespace fleetgw::ingest {

bool is_transient(const PgError& e) {
  const std::string& s = e.sqlstate();
  // No SQLSTATE: the failure happened below SQL (connection lost, server gone).
  if (s.size() < 2) return true;
  const std::string_view cls = std::string_view(s).substr(0, 2);
  return cls == "08" || cls == "40" || cls == "53" || cls == "57" || cls == "58";
}

IngestStore::IngestStore(std::string conninfo, std::size_t rows_per_statement)
    : conninfo_(std::move(conninfo)),
      rows_per_statement_(std::max<std::size_t>(1, rows_per_statement)) {}

int IngestStore::connect() {
  conn_.reset();
  conn_.emplace(conninfo_);
  return migrate(*conn_);
}

PgConnection& IngestStore::conn() {
  if (!conn_ || !conn_->ok()) connect();
  return *conn_;
}

const std::string& IngestStore::insert_sql(const TableSpec& t, std::size_t rows) {
  std::string& sql = sql_cache_[{t.table, rows}];
  if (!sql.empty()) return sql;
  sql = "INSERT INTO " + std::string(t.table) + " (" + std::string(t.columns) + ") VALUES ";
  int n = 1;
  for (std::size_t r = 0; r < rows; ++r) {
    sql += r ? ",(" : "(";
    for (int c = 0; c < t.column_count; ++c) sql += (c ? ",$" : "$") + std::to_string(n++);
    sql += ")";
  }
  sql += " " + std::string(t.on_conflict);
  return sql;
}

WriteStats IngestStore::write(const Decoded& d) {
  PgConnection& c = conn();
  WriteStats stats;
  PgTransaction tx(c);
  const bool latest_only = std::all_of(d.rows.begin(), d.rows.end(),
                                       [](const RowSet& r) { return r.table->latest_value; });
  if (latest_only) {
    // A status or state row is replaced by the next one (and the broker delivers the retained
    // message again at every subscribe): not worth a WAL flush (3 ms here) before the ack.
    c.exec("SET LOCAL synchronous_commit = off", "latest value commit");
  }
  if (!d.ranges.empty()) {
    // One lock per message (a message is one vehicle's): concurrent writers of one vehicle
    // queue here, before any row lock, so range merging never deadlocks.
    const PgParam key[] = {d.vehicle_id + "/" + d.store_id};
    c.exec_params("SELECT pg_advisory_xact_lock(hashtextextended($1, 0))", key, "vehicle lock");
  }
  for (const RowSet& set : d.rows) {
    const std::size_t cols = static_cast<std::size_t>(set.table->column_count);
    const std::size_t total = set.rows();
    for (std::size_t first = 0; first < total; first += rows_per_statement_) {
      const std::size_t n = std::min(rows_per_statement_, total - first);
      const std::span<const PgParam> values(set.values.data() + first * cols, n * cols);
      const PgResult r = c.exec_params(insert_sql(*set.table, n), values, set.table->table);
      stats.inserted += r.affected();
      stats.duplicates += static_cast<std::int64_t>(n) - r.affected();
    }
  }
  for (const SequenceRange& range : d.ranges) {
    // Delete every range touching or adjacent to [first, last] and insert their union.
    const PgParam p[] = {d.vehicle_id, d.store_id, std::to_string(range.first),
                         std::to_string(range.last)};
    c.exec_params(
        "WITH gone AS (DELETE FROM sequence_ranges WHERE vehicle_id = $1 AND store_id = $2 "
        "AND first_seq <= $4::bigint + 1 AND last_seq >= $3::bigint - 1 "
        "RETURNING first_seq, last_seq) "
        "INSERT INTO sequence_ranges (vehicle_id, store_id, first_seq, last_seq) "
        "SELECT $1, $2, LEAST($3::bigint, min(first_seq)), GREATEST($4::bigint, max(last_seq)) "
        "FROM gone",
        p, "sequence_ranges");
  }
  tx.commit();
  return stats;
}

void IngestStore::write_reject(std::string_view topic, const Reject& r, std::size_t payload_bytes) {
  const PgParam p[] = {common::untrusted_excerpt(topic, 256),
                       r.code + ": " + common::truncate_utf8(r.detail, 512),
                       std::to_string(payload_bytes)};
  conn().exec_params(
      "INSERT INTO rejected_messages (topic, reason, payload_bytes) VALUES ($1, $2, $3)", p,
      "rejected_messages");
}

std::vector<Gap> IngestStore::gaps() {
  const PgResult r = conn().exec(
      "SELECT vehicle_id, store_id, first_missing, last_missing FROM sequence_gaps "
      "ORDER BY vehicle_id, store_id, first_missing",
      "gap report");
  std::vector<Gap> out;
  for (int i = 0; i < r.rows(); ++i) {
    out.push_back(
        {std::string(r.text(i, 0)), std::string(r.text(i, 1)), r.int64(i, 2), r.int64(i, 3)});
  }
  return out;
}

}  // namespace fleetgw::ingest
