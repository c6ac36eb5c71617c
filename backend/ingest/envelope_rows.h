// From one received MQTT message (topic + payload bytes) to the rows the ingest writes: the
// pure, database-free half of `fleetgw ingest`, so every rule here is unit-tested without
// PostgreSQL or a broker.
//
// Contract:
//  * decode_message() never throws on any input and never crashes: the payload and the topic are
//    untrusted bytes. It returns either a Decoded (rows + the sequence ranges they account for)
//    or a Reject {code, detail}: `code` is a short fixed string naming the reason class (for
//    "logged once per reason" and counting), `detail` says what and where (field, value excerpt
//    made safe with untrusted_excerpt).
//  * Topics are <prefix>/<vehicle_id>/<leaf>; leaves as in docs/uplink.md. `cmd` carries a
//    fleetgw.v1.SignedCommand, everything else a fleetgw.v1.Envelope whose vehicle_id must equal
//    the topic's and whose body must be the leaf's kind.
//  * Records (every kind but status and state) need sequence >= 1 (command results may have 0:
//    published unstored). Rows keep the wire's units; uint32 values above INT32_MAX and uint64
//    values above INT64_MAX, strings with a NUL byte or longer than kMaxText bytes, are rejected
//    (PostgreSQL could not store them as such, and no gateway sends them).
//  * Sequence ranges: the sorted, merged runs of record sequences of the message (a telemetry
//    batch: its samples'), plus for an EvictionReport its [first_sequence, last_sequence]: what
//    the message accounts for in the gap tracking (docs/backend.md).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "backend/common/pg.h"

namespace fleetgw::ingest {

// One destination table: its INSERT column list and conflict clause.
struct TableSpec {
  std::string_view table;
  std::string_view columns;  // "a, b, c"
  int column_count;
  std::string_view on_conflict;  // "ON CONFLICT DO NOTHING" or an upsert
  // Latest values (status, state), replaced by the next message: committed without waiting for
  // the WAL flush (docs/backend.md "Exactly once").
  bool latest_value = false;
  // A change log (status_history): a row the statement skips is an unchanged state, not a
  // duplicate record.
  bool history = false;
};

// Rows for one table, built straight into COPY's text format (copy_text.h) as the message is
// decoded: what the batch's COPY sends as it is, without committed_at_us (added per batch).
// No string per value (issue 25: a heap string per value was the worker's largest cost).
struct RowSet {
  const TableSpec* table = nullptr;
  std::string copy;  // `row_count` rows, each ended by a newline
  std::size_t row_count = 0;
  std::size_t rows() const { return row_count; }
  // Every value, row-major (rows() * table->column_count), parsed back from `copy` (tests).
  std::vector<PgParam> values() const;
};

struct SequenceRange {
  std::uint64_t first;
  std::uint64_t last;
  bool operator==(const SequenceRange&) const = default;
};

struct Decoded {
  std::string vehicle_id;
  std::string store_id;
  std::vector<RowSet> rows;
  std::vector<SequenceRange> ranges;
  // Records in the message (samples for telemetry); 0 for status/state/commands.
  std::size_t records = 0;
};

struct Reject {
  std::string code;
  std::string detail;
};

constexpr std::size_t kMaxText = 1024;
// Samples per telemetry message: the gateway's own largest batch (`[mqtt] batch_max_samples`
// is at most 10,000). A larger one is rejected as too_many_samples before any row is built, so
// one message's rows stay within ~10 MB (docs/backend.md "Memory").
constexpr std::size_t kMaxSamples = 10'000;

std::variant<Decoded, Reject> decode_message(std::string_view topic_prefix, std::string_view topic,
                                             std::string_view payload);

// The table an Envelope body field's rows go to, by the record-kind table's ingest_table
// (proto/record_kinds.h); nullptr for a field that is no known body.
const TableSpec* table_of(int envelope_field);

// Sorted, merged runs of `seqs` (consumed; duplicates allowed).
std::vector<SequenceRange> to_ranges(std::vector<std::uint64_t> seqs);

}  // namespace fleetgw::ingest
