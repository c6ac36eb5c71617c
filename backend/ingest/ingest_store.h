// The ingest's PostgreSQL side: one decoded message → one transaction.
//
// Contract:
//  * IngestStore connects lazily (and again after a broken connection) and applies the
//    migrations (migrations.h) at its first connection.
//  * write(d) runs ONE transaction: a per-(vehicle, store) advisory lock when it has sequence
//    ranges to merge (taken first, so two
//    workers writing the same vehicle serialise instead of deadlocking), every RowSet as
//    multi-row INSERTs of at most `rows_per_statement` rows with the table's conflict clause
//    (records: ON CONFLICT DO NOTHING on (vehicle_id, store_id, sequence)), then each sequence
//    range merged into sequence_ranges; COMMIT. It returns only after the commit succeeded
//    (durably: WAL flushed, except for messages of latest-value tables only, status and state,
//    committed with synchronous_commit off); on any failure nothing of the message is kept and
//    PgError is thrown.
//  * is_transient(e): a failure worth retrying (connection lost, server shutting down,
//    serialisation failure, resources); anything else (the server refused the data) is not, and
//    the caller records the message as rejected instead of retrying it for ever.
//  * write_reject() stores one row in rejected_messages (topic and detail as untrusted excerpts).
//  * gaps() = the view sequence_gaps: holes in the accounted sequences, per (vehicle, store).
//  * Not thread-safe: one IngestStore per worker thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "gateway/ingest/envelope_rows.h"
#include "gateway/ingest/pg.h"

namespace fleetgw::ingest {

struct WriteStats {
  std::int64_t inserted = 0;    // rows the statements added or updated
  std::int64_t duplicates = 0;  // rows already there (ON CONFLICT DO NOTHING)
};

struct Gap {
  std::string vehicle_id;
  std::string store_id;
  std::int64_t first_missing = 0;
  std::int64_t last_missing = 0;
};

bool is_transient(const PgError& e);

class IngestStore {
 public:
  IngestStore(std::string conninfo, std::size_t rows_per_statement);

  WriteStats write(const Decoded& d);
  void write_reject(std::string_view topic, const Reject& r, std::size_t payload_bytes);
  std::vector<Gap> gaps();

  // Connects (and migrates) now; throws PgError. Returns the migrations applied.
  int connect();

 private:
  PgConnection& conn();
  const std::string& insert_sql(const TableSpec& t, std::size_t rows);

  std::string conninfo_;
  std::size_t rows_per_statement_;
  std::optional<PgConnection> conn_;
  std::map<std::pair<std::string_view, std::size_t>, std::string> sql_cache_;
};

}  // namespace fleetgw::ingest
