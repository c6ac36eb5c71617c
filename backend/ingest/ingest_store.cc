// PostgreSQL writes of the ingest (ingest_store.h): one INSERT ... SELECT FROM unnest(arrays)
// per table, ranges appended by one COPY, one transaction per batch; ranges compacted later.
#include "backend/ingest/ingest_store.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <map>
#include <utility>

#include "backend/ingest/campaign_rows.h"
#include "backend/ingest/copy_text.h"
#include "backend/ingest/migrations.h"
#include "backend/ingest/record_rows.h"
#include "backend/ingest/safe_text.h"

namespace fleetgw::ingest {
namespace {

// Every destination table, in the order a batch writes them.
constexpr std::array<const TableSpec*, 15> kTables = {
    &rows::kRides,  &rows::kFaults,        &rows::kTelemetry,     &rows::kPacks,
    &rows::kLocks,  &rows::kResults,       &rows::kCommands,      &rows::kInfo,
    &rows::kAlarms, &rows::kEvictions,     &rows::kZones,         &rows::kStatus,
    &rows::kState,  &rows::kStatusHistory, &kCampaignSamplesTable};

// A text[] literal of `items` (quoted and escaped as PostgreSQL's array input expects).
std::string text_array(const std::vector<std::string>& items) {
  std::string out = "{";
  for (const std::string& s : items) {
    out += out.size() > 1 ? ",\"" : "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') out += '\\';
      out += c;
    }
    out += '"';
  }
  return out + "}";
}

// Column 1 of a vehicle_state row (updated_at_us; never escaped: a number) as a number.
std::int64_t updated_at(std::string_view row) {
  const std::size_t from = row.find('\t') + 1;
  const std::string_view v = row.substr(from, row.find('\t', from) - from);
  std::int64_t n = 0;
  std::from_chars(v.data(), v.data() + v.size(), n);
  return n;
}

// Column 0 of a row (vehicle_id of status and state), still escaped: equal exactly when the
// values are (copy_text.h).
std::string_view first_value(std::string_view row) {
  return row.substr(0, row.find('\t'));
}

// Ranges of the batch merged per (vehicle, store). Views into the batch's messages (which
// outlive the write): a key of two strings cost two copies per message, found or not.
using RangeKey = std::pair<std::string_view, std::string_view>;
std::map<RangeKey, std::vector<SequenceRange>> merged_ranges(
    std::span<const Decoded* const> messages) {
  std::map<RangeKey, std::vector<SequenceRange>> all;
  for (const Decoded* d : messages) {
    if (d->ranges.empty()) continue;
    auto& v = all[{d->vehicle_id, d->store_id}];
    v.insert(v.end(), d->ranges.begin(), d->ranges.end());
  }
  for (auto& [key, v] : all) {
    std::sort(v.begin(), v.end(),
              [](const SequenceRange& a, const SequenceRange& b) { return a.first < b.first; });
    std::vector<SequenceRange> out;
    for (const SequenceRange& r : v) {
      // r.first - 1 instead of last + 1: a range may end at 2^63-1.
      if (!out.empty() && r.first - 1 <= out.back().last) {
        out.back().last = std::max(out.back().last, r.last);
      } else {
        out.push_back(r);
      }
    }
    v = std::move(out);
  }
  return all;
}

}  // namespace

bool is_transient(const PgError& e) {
  const std::string& s = e.sqlstate();
  // No SQLSTATE: the failure happened below SQL (connection lost, server gone).
  if (s.size() < 2) return true;
  const std::string_view cls = std::string_view(s).substr(0, 2);
  return cls == "08" || cls == "40" || cls == "53" || cls == "57" || cls == "58";
}

IngestStore::IngestStore(std::string conninfo, std::size_t /*unused_rows_per_statement*/)
    : conninfo_(std::move(conninfo)) {}

int IngestStore::connect() {
  conn_.reset();
  insert_sql_.clear();
  conn_.emplace(conninfo_);
  return migrate(*conn_);
}

PgConnection& IngestStore::conn() {
  if (!conn_ || !conn_->ok()) connect();
  return *conn_;
}

const std::string& IngestStore::insert_sql(PgConnection& c, const TableSpec& t) {
  std::string& sql = insert_sql_[&t];
  if (!sql.empty()) return sql;
  // Every column travels as a text[] parameter and is cast to its column's type: one statement
  // per table and batch, no temporary table (whose truncation at each commit cost more than
  // the rows). The types come from the catalog, in the spec's column order.
  const PgParam p[] = {std::string(t.table), std::string(t.columns)};
  const PgResult types = c.exec_params(
      "SELECT format_type(a.atttypid, a.atttypmod) FROM unnest(string_to_array($2, ', ')) WITH "
      "ORDINALITY AS k(name, ord) JOIN pg_attribute a ON a.attrelid = $1::regclass AND "
      "a.attname = k.name ORDER BY k.ord",
      p, "column types");
  if (types.rows() != t.column_count) {
    throw PgError(fmt::format("{}: {} of {} columns found", t.table, types.rows(), t.column_count),
                  "");
  }
  std::string select;
  std::string from;
  std::string names;
  for (int i = 0; i < t.column_count; ++i) {
    select += fmt::format("{}u.c{}::{}", i ? ", " : "", i, types.text(i, 0));
    from += fmt::format("{}${}::text[]", i ? ", " : "", i + 1);
    names += fmt::format("{}c{}", i ? ", " : "", i);
  }
  // Prepared once per connection: the statement's name is what the batch executes (kept only
  // once the server has it).
  const std::string name = fmt::format("insert_{}", t.table);
  c.prepare(name,
            fmt::format("INSERT INTO {} ({}) SELECT {} FROM unnest({}) AS u({}) {}", t.table,
                        t.columns, select, from, names, t.on_conflict),
            t.column_count, t.table);
  sql = name;
  return sql;
}

void IngestStore::insert_reject(PgConnection& c, const RejectRow& r) {
  const PgParam p[] = {untrusted_excerpt(r.topic, 256),
                       r.reject.code + ": " + truncate_utf8(r.reject.detail, 512),
                       std::to_string(r.payload_bytes)};
  c.exec_params("INSERT INTO rejected_messages (topic, reason, payload_bytes) VALUES ($1, $2, $3)",
                p, "rejected_messages");
}

WriteStats IngestStore::write_all(std::span<const Decoded* const> messages,
                                  std::span<const RejectRow> rejects) {
  PgConnection& c = conn();
  WriteStats stats;
  PgTransaction tx(c);
  bool latest_only = !messages.empty();
  for (const Decoded* d : messages) {
    for (const RowSet& r : d->rows) latest_only = latest_only && r.table->latest_value;
  }
  if (latest_only) {
    // Status and state rows are replaced by the next ones (and a retained message comes again
    // at every subscribe): not worth a WAL flush before the acknowledgement.
    c.exec("SET LOCAL synchronous_commit = off", "latest value commit");
  }
  const auto ranges = merged_ranges(messages);
  if (!ranges.empty()) {
    // One lock per (vehicle, store), all taken before any row lock, in one order (by hash).
    std::vector<std::string> keys;
    for (const auto& [key, v] : ranges) {
      keys.push_back(std::string(key.first) + "/" + std::string(key.second));
    }
    const PgParam p[] = {text_array(keys)};
    c.exec_params(
        "SELECT pg_advisory_xact_lock(k) FROM (SELECT DISTINCT hashtextextended(u, 0) AS k "
        "FROM unnest($1::text[]) AS u ORDER BY 1) s",
        p, "vehicle locks");
  }
  if (hook_) hook_(BatchPoint::kBeforeCopy);
  if (!latest_only && !messages.empty()) {
    // committed_at_us of every row of the batch: the database's clock once, as the batch is
    // written (the column's default reads it: migration 9).
    c.exec("SELECT set_config('fleet.batch_us', fleet_now_us()::text, true)", "batch stamp");
  }
  // The batch's row sets by destination table, in one pass over the messages.
  std::array<std::vector<const RowSet*>, kTables.size()> sets_of;
  for (const Decoded* d : messages) {
    for (const RowSet& set : d->rows) {
      const auto at = std::find(kTables.begin(), kTables.end(), set.table);
      if (at != kTables.end())
        sets_of[static_cast<std::size_t>(at - kTables.begin())].push_back(&set);
    }
  }
  std::vector<std::string_view> fields;
  for (std::size_t table = 0; table < kTables.size(); ++table) {
    const TableSpec* t = kTables[table];
    const std::size_t cols = static_cast<std::size_t>(t->column_count);
    if (sets_of[table].empty()) continue;
    if (!t->latest_value && !t->history && copy_rows(c, *t, sets_of[table], stats)) continue;
    // The rows one by one: latest values (one per vehicle), the history, or a COPY that found a
    // row already there (a redelivery).
    std::vector<std::string_view> staged_rows;
    for (const RowSet* set : sets_of[table]) {
      std::string_view rest = set->copy;
      while (!rest.empty()) staged_rows.push_back(next_row(rest));
    }
    std::int64_t superseded = 0;
    if (t->latest_value) {
      // An upsert may touch a row once per statement: keep the batch's last status per vehicle
      // and its newest state (the others are older than it: out of order).
      std::map<std::string_view, std::size_t> newest;
      for (std::size_t i = 0; i < staged_rows.size(); ++i) {
        auto [it, fresh] = newest.try_emplace(first_value(staged_rows[i]), i);
        if (fresh) continue;
        if (t != &rows::kState ||
            updated_at(staged_rows[i]) >= updated_at(staged_rows[it->second])) {
          it->second = i;  // arrived later and is newer: as if applied after the other
        } else {
          ++superseded;  // a state older than one the batch already has: out of order
        }
      }
      std::vector<std::string_view> kept;
      kept.reserve(newest.size());
      for (const auto& [vehicle, i] : newest) kept.push_back(staged_rows[i]);
      staged_rows = std::move(kept);
    }
    const std::string& statement = insert_sql(c, *t);
    // Each column a text[] literal, made from the rows' COPY text without a string per value.
    std::vector<PgParam> columns(cols, std::string("{"));
    for (const std::string_view row : staged_rows) {
      split_row(row, fields);
      for (std::size_t i = 0; i < cols && i < fields.size(); ++i) {
        append_array_element(*columns[i], fields[i]);
      }
    }
    for (PgParam& column : columns) *column += '}';
    const PgResult r = c.exec_prepared(statement, columns, t->table);
    const std::int64_t staged = static_cast<std::int64_t>(staged_rows.size());
    stats.inserted += r.affected();
    if (t == &rows::kState) {
      stats.stale_states += staged - r.affected() + superseded;
    } else if (!t->latest_value && !t->history) {
      stats.duplicates += staged - r.affected();
    }
  }
  if (!ranges.empty()) {
    // One row per (vehicle, store) and range of the batch, appended (migration 11: merged
    // later by a compaction, read merged through the view sequence_ranges). No index on the
    // table, so nothing here waits for another worker or conflicts with a redelivery.
    std::string& data = copy_buffer_;
    data.clear();
    std::int64_t appended = 0;
    for (const auto& [key, v] : ranges) {
      for (const SequenceRange& r : v) {
        append_copy_text(data, key.first);
        data += '\t';
        append_copy_text(data, key.second);
        data += fmt::format("\t{}\t{}\n", r.first, r.last);
        ++appended;
      }
    }
    c.copy_in("COPY sequence_ranges_new (vehicle_id, store_id, first_seq, last_seq) FROM STDIN",
              data, "sequence_ranges_new");
    ranges_appended_ += appended;
  }
  for (const RejectRow& r : rejects) insert_reject(c, r);
  if (hook_) hook_(BatchPoint::kAfterCopy);
  tx.commit();
  if (hook_) hook_(BatchPoint::kAfterCommit);
  return stats;
}

bool IngestStore::copy_rows(PgConnection& c, const TableSpec& t,
                            std::span<const RowSet* const> sets, WriteStats& stats) {
  // The messages' COPY text as it is, one append per message, into one buffer kept for the next
  // table and batch (its capacity stays).
  std::string& data = copy_buffer_;
  data.clear();
  std::size_t size = 0;
  for (const RowSet* set : sets) size += set->copy.size();
  data.reserve(size);
  for (const RowSet* set : sets) data += set->copy;
  c.exec("SAVEPOINT ingest_copy", "savepoint");
  try {
    const std::int64_t n =
        c.copy_in(fmt::format("COPY {} ({}) FROM STDIN", t.table, t.columns), data, t.table);
    c.exec("RELEASE SAVEPOINT ingest_copy", "savepoint");
    stats.inserted += n;
    return true;
  } catch (const PgError& e) {
    // A row already there (a redelivery): the table's ON CONFLICT statement instead. Anything
    // else (a poison row, the server away) is the caller's.
    if (e.sqlstate() != "23505") throw;
  }
  c.exec("ROLLBACK TO SAVEPOINT ingest_copy", "savepoint");
  return false;
}

BatchResult IngestStore::write_batch(std::span<const Decoded* const> messages,
                                     std::span<const RejectRow> rejects) {
  BatchResult result;
  result.refused.resize(messages.size());
  try {
    result.stats = write_all(messages, rejects);
    maybe_compact();
    return result;
  } catch (const PgError& e) {
    if (is_transient(e) || messages.empty()) throw;
  }
  // A poison row: each message alone, so the others still commit.
  for (std::size_t i = 0; i < messages.size(); ++i) {
    try {
      result.stats += write_all(messages.subspan(i, 1), {});
    } catch (const PgError& e) {
      if (is_transient(e)) throw;
      result.refused[i] = Reject{"database_refused", e.what()};
    }
  }
  if (!rejects.empty()) write_all({}, rejects);
  maybe_compact();
  return result;
}

std::int64_t IngestStore::compact_ranges() {
  const std::int64_t moved =
      conn().exec("SELECT fleet_compact_sequence_ranges()", "range compaction").int64(0, 0);
  ranges_appended_ = 0;
  last_compaction_ = std::chrono::steady_clock::now();
  return moved;
}

void IngestStore::maybe_compact() {
  if (ranges_appended_ == 0) return;
  if (ranges_appended_ < compact_after_ranges_ &&
      std::chrono::steady_clock::now() - last_compaction_ < compact_every_) {
    return;
  }
  try {
    compact_ranges();
  } catch (const PgError&) {
    // The batch is committed: a failed compaction only leaves its ranges appended (the view
    // reads them merged); a later batch tries again. Not the caller's to retry.
    last_compaction_ = std::chrono::steady_clock::now();
  }
}

WriteStats IngestStore::write(const Decoded& d) {
  const Decoded* one[] = {&d};
  return write_all(one, {});
}

void IngestStore::write_reject(std::string_view topic, const Reject& r, std::size_t payload_bytes) {
  insert_reject(conn(), RejectRow{topic, r, payload_bytes});
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

int IngestStore::maintain_partitions(int days_ahead, int retention_days) {
  const PgParam p[] = {std::to_string(days_ahead), std::to_string(retention_days)};
  return static_cast<int>(
      conn()
          .exec_params("SELECT fleet_maintain_telemetry_partitions($1::int, $2::int)", p,
                       "telemetry partitions")
          .int64(0, 0));
}

}  // namespace fleetgw::ingest
