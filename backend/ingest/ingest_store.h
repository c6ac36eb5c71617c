// The ingest's PostgreSQL side: a batch of decoded messages → one transaction.
//
// Contract:
//  * IngestStore connects lazily (and again after a broken connection) and applies the
//    migrations (migrations.h) at its first connection.
//  * write_batch(messages) writes every message of the batch in ONE transaction, at bulk speed:
//    the batch's stamp set once (`fleet.batch_us`: every row's committed_at_us, migration 9),
//    per record table one COPY of the messages' COPY text (under a savepoint), and when one is
//    already there (a redelivery: unique violation) instead, as for the latest-value tables,
//    one `INSERT ... SELECT ... FROM unnest($1::text[], ...) ON CONFLICT`
//    with every column of the batch's rows as one array parameter (records: DO NOTHING on
//    their key; latest values: an upsert, the batch's newest row per vehicle only); then the
//    batch's sequence ranges, merged per (vehicle, store) in memory and appended to
//    sequence_ranges_new by one COPY (migration 11: compact_ranges() merges them into the
//    stored ranges later; the view sequence_ranges reads both merged). Per-(vehicle, store)
//    advisory locks, taken first and in one fixed order, only when the batch has ranges (two
//    workers writing one vehicle serialise instead of deadlocking on its records' keys). It
//    returns only after the commit succeeded (WAL flushed, except for batches of latest-value
//    rows only: synchronous_commit off). After a commit, every 20,000 ranges or 30 s, it
//    compacts the appended ranges (compact_ranges(); a failure there is not the batch's).
//  * A batch the server refuses for a reason that is not transient (a poison row) is written
//    again one message per transaction: the messages the server refuses are returned as
//    rejected (reason `database_refused` with the server's message, not written), the others
//    are committed. A transient failure (is_transient) throws PgError: nothing of the batch is
//    known committed; the caller retries the whole batch (idempotent).
//  * write(d) = one message in one transaction, PgError on any failure (tests, tools).
//  * Counters: `inserted` rows added (records) or replaced (latest values); `duplicates`
//    records (and commands) already there: redeliveries; `stale_states` VehicleState upserts
//    older than the stored state (out of order, not applied), counted apart from duplicates.
//  * write_reject() stores one row in rejected_messages (topic and detail as untrusted excerpts).
//  * gaps() = the view sequence_gaps: holes in the accounted sequences, per (vehicle, store).
//  * Not thread-safe: one IngestStore per thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "backend/common/pg.h"
#include "backend/ingest/envelope_rows.h"

namespace fleetgw::ingest {

struct WriteStats {
  std::int64_t inserted = 0;
  std::int64_t duplicates = 0;
  std::int64_t stale_states = 0;
  WriteStats& operator+=(const WriteStats& o) {
    inserted += o.inserted;
    duplicates += o.duplicates;
    stale_states += o.stale_states;
    return *this;
  }
};

struct BatchResult {
  WriteStats stats;
  // One entry per message of the batch: set when the database refused that message.
  std::vector<std::optional<Reject>> refused;
};

// A message rejected before the database (decode_message) or by it, for rejected_messages.
struct RejectRow {
  std::string_view topic;
  Reject reject;
  std::size_t payload_bytes = 0;
};

struct Gap {
  std::string vehicle_id;
  std::string store_id;
  std::int64_t first_missing = 0;
  std::int64_t last_missing = 0;
};

bool is_transient(const PgError& e);

// Test hook points inside a batch (FLEETGW_INGEST_CRASH_AT, ingest_worker.h).
enum class BatchPoint { kBeforeCopy, kAfterCopy, kAfterCommit };

class IngestStore {
 public:
  explicit IngestStore(std::string conninfo, std::size_t unused_rows_per_statement = 0);

  // `rejects` are stored in rejected_messages in the same transaction.
  BatchResult write_batch(std::span<const Decoded* const> messages,
                          std::span<const RejectRow> rejects = {});
  WriteStats write(const Decoded& d);
  void write_reject(std::string_view topic, const Reject& r, std::size_t payload_bytes);
  std::vector<Gap> gaps();
  // Creates the telemetry partitions of [now - 1 day, now + days_ahead] and drops those that
  // ended more than retention_days ago (0: keep all). Returns the partitions dropped.
  int maintain_partitions(int days_ahead, int retention_days);
  // Merges the appended sequence ranges into the stored ones now (migration 11); returns the
  // appended rows moved (0 when another worker's compaction runs). write_batch calls it after
  // a commit every so many ranges or seconds; throws PgError.
  std::int64_t compact_ranges();
  // When write_batch compacts: after `after_ranges` appended by this store or `every` since its
  // last compaction, whichever comes first (tests: 1).
  void set_compaction(std::int64_t after_ranges, std::chrono::seconds every) {
    compact_after_ranges_ = after_ranges;
    compact_every_ = every;
  }

  // Connects (and migrates) now; throws PgError. Returns the migrations applied.
  int connect();
  // Called at each point of a batch (tests crash the process there).
  void set_batch_hook(std::function<void(BatchPoint)> hook) { hook_ = std::move(hook); }

 private:
  PgConnection& conn();
  WriteStats write_all(std::span<const Decoded* const> messages,
                       std::span<const RejectRow> rejects);
  void insert_reject(PgConnection& c, const RejectRow& r);
  // compact_ranges() when enough ranges or time went by since the last one; never throws.
  void maybe_compact();
  // The fast path of a record table: the batch's rows (the messages' COPY text as it is) by
  // one COPY, under a savepoint; committed_at_us is the column's default, the batch's stamp
  // (migration 9). False (rolled back) when a row is already there.
  bool copy_rows(PgConnection& c, const TableSpec& t, std::span<const RowSet* const> sets,
                 WriteStats& stats);
  // The name of t's prepared INSERT on connection c (prepared at its first use).
  const std::string& insert_sql(PgConnection& c, const TableSpec& t);

  std::string conninfo_;
  std::optional<PgConnection> conn_;
  // Prepared statements of this connection, per table.
  std::map<const TableSpec*, std::string> insert_sql_;
  // A compaction (migration 11) every 20,000 ranges or 30 s: rarely enough that each (vehicle,
  // store) gathers several batches' ranges per compaction (a drain's 2,000 vehicles: ~1,500-2,000
  // ranges per batch), often enough that the view sequence_ranges merges few rows and that one
  // compaction (~2 µs of server time per appended range) holds the next batch back ~40 ms.
  std::int64_t compact_after_ranges_ = 20000;
  std::chrono::seconds compact_every_{30};
  std::int64_t ranges_appended_ = 0;  // by this store since its last compaction
  std::chrono::steady_clock::time_point last_compaction_ = std::chrono::steady_clock::now();
  std::string copy_buffer_;  // a table's COPY data, reused
  std::function<void(BatchPoint)> hook_;
};

}  // namespace fleetgw::ingest
