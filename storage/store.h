// fleetgw's persistent store: the typed tables of storage/records.h plus the uplink OUTBOX, in
// one SQLite file (WAL mode), so a unit that stays offline for days loses nothing.
//
// Contract:
// - One Store per database file and per process, used from one thread (the gateway's storage
//   strand). A second Store on the same file (in this or another process) is refused: the
//   store holds an exclusive flock on "<path>.lock" for its lifetime. Read-only tools (the
//   sqlite3 CLI, technician exports through another process) may read concurrently (WAL).
// - Opening: the file is created if absent. A file that is not SQLite (bad header, garbage),
//   that SQLite reports as corrupt, or that fails PRAGMA quick_check is never overwritten: it
//   is renamed, with its -wal/-shm, to "<path>.corrupt-<UTC timestamp>" (StoreOptions::env's
//   wall clock), an error is logged and
//   a fresh database is started (moved_aside_path() tells the gateway, which should report it).
//   A database whose schema version is newer than this binary stops start-up with
//   SchemaTooNewError (path and both versions). Migrations (storage/schema.h) run at open.
// - write(Batch) stores every record of the batch and queues its uplink payload (when it has
//   one) in the outbox in ONE transaction, with the per-vehicle sequence counter persisted in
//   the same transaction: either the whole batch and its sequence numbers are on disk, or none
//   of it is. Sequence numbers are allocated gap-free and are never reused, even after acks,
//   evictions, crashes or restarts.
// - Errors never escape the write and ack paths (nothing on the hot path throws): write()
//   returns what it stored (Written) or a Status (env/status.h) and then stores nothing of the
//   batch: kInvalid for bad input, naming the batch entry and field; kFull, kIo, kOther for
//   disk and SQLite errors. ack(),
//   release(), peek_outbox() and outbox_depth() never throw either. Every failed write attempt
//   is recorded in health() (reason, count, since when); the next successful one clears
//   `failing`. Only the constructor throws (cannot open, not a store, schema too new...).
// - Durability: Durability::kNormal (default, PRAGMA synchronous=NORMAL) makes every returned
//   write() survive a crash or kill of the process; after a power cut the last commits before
//   the cut may be lost, but the database is never corrupted. Durability::kFull fsyncs the WAL
//   at every commit so a returned write() also survives power loss.
// - Outbox: priority 0 is the most urgent (OutboxPriority: alarms and command results 0,
//   faults 1, rides 2,
//   lock events 3, pack statistics 4, telemetry 5; eviction reports go at priority 1;
//   campaign records 6..15, below all of them: OutboxPriority::kCampaign + the campaign's).
//   peek_outbox() returns entries in (priority, seq) order, skipping the ones in flight, and
//   marks what it returns as in flight (in memory only). ack() deletes exactly the
//   acknowledged rows; release() puts in-flight entries back (publish failed).
// - Disk budget (storage/store_budget.h): StoreOptions::max_bytes covers everything the store
//   writes: the database pages, the WAL (bounded: checkpointed when it reaches its allowance,
//   never left above it) and the shared-memory file. At open the budget is clamped, with a
//   warning, to what the file system can hold (statvfs). Inside the budget a reserve is kept
//   for records that are never evicted: telemetry (then campaign records, lowest campaign
//   priority first, then pack snapshots) is evicted, oldest first, as soon as the live pages
//   pass (budget - WAL allowance - reserve), so the command journal, command results, faults,
//   rides and lock events can still be written when telemetry has filled the rest. When SQLite
//   reports SQLITE_FULL anyway (the disk filled up from elsewhere), write() checkpoints, evicts
//   a chunk of telemetry (then campaign records, then pack snapshots),
//   gives the pages back to the file system and retries before giving up. Each eviction is
//   counted per table (persisted), logged, queued as an eviction_report outbox entry (JSON)
//   and returned from write().
// - WAL checkpoints run outside the write transaction: checkpoint_if_due() (the recorder calls
//   it after a flush; a caller may call it when idle) asks the background checkpointer (its own
//   thread and connection, PASSIVE checkpoints) once the WAL holds half its allowance, and
//   returns at once; write() itself checkpoints (PASSIVE, inline) only when the WAL reached the
//   whole allowance.
// - Read-only (StoreOptions::read_only, the `fleetgw db` tools): opened with
//   SQLITE_OPEN_READONLY, no lock file, no migration, no move-aside, never creates, moves or
//   renames a file; works while the service writes (WAL). A missing file, a file that is not
//   SQLite or an SQLite file without the fleetgw tables throws NotAStoreError naming the path.
//   write()/ack() on a read-only store return an error.
// - The directory of StoreOptions::path must exist; it is never created (a typo in
//   storage.path must not silently start an empty store elsewhere).
// - Technician tools: stats() and export_table() return data; the CLI formats it.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "env/env.h"
#include "env/status.h"
#include "storage/health.h"
#include "storage/records.h"

namespace spdlog {
class logger;
}

namespace fleetgw::storage {

enum class Durability : std::uint8_t { kNormal, kFull };

struct StoreOptions {
  std::string path{};           // database file
  std::uint64_t max_bytes = 0;  // disk budget; config `max_mb` * 1024 * 1024; 0 = unlimited
  double low_water = 0.9;       // eviction frees down to low_water * max_bytes
  Durability durability = Durability::kNormal;
  // Upper bound of the WAL between checkpoints, in pages (0: derived from the budget, at most
  // 1000 pages = 4 MB; with a budget, an eighth of it).
  int wal_autocheckpoint_pages = 0;
  // Open for inspection only (see the contract).
  bool read_only = false;
  // Hard cap of the database file in pages (PRAGMA max_page_count), 0 = none. Beyond it SQLite
  // reports SQLITE_FULL exactly as a full disk does (tests use it to simulate one).
  std::uint64_t max_page_count = 0;
  std::shared_ptr<spdlog::logger> logger{};  // default: spdlog's default logger
  // The environment (env/env.h): the wall clock that names a moved-aside corrupt file and
  // stamps failing_since_us, the steady clock of the log rate limits, the checkpointer's
  // thread, the renames of a move-aside and the free-space check. Never null.
  Env* env = &Env::system();
  // The payload of an eviction report queued by an eviction pass (`seq`: the report's own
  // outbox sequence number). The gateway sets its fleetgw.v1.EvictionReport encoder
  // (gateway/domain/payloads.h), so the report is stored as the wire bytes it is published as;
  // default: EvictionPass::to_json() (storage knows no protobuf).
  std::function<Bytes(const EvictionPass&, std::uint64_t seq)> encode_eviction_report{};
};

// A record plus, optionally, its uplink payload. With a payload the record is queued in the
// outbox in the same transaction; without one it is only stored (e.g. an open ride's periodic
// checkpoint, which is sent once the ride closes).
template <typename T>
struct PendingRow {
  T record;
  std::optional<Bytes> uplink;
};

// An outbox entry without a table row behind it (device info, status...).
struct UplinkMessage {
  OutboxKind kind = OutboxKind::kInfo;
  int priority = kLowestPriority;
  Bytes payload;
};

// Everything the gateway accumulated since its last write(). Rides are upserted by ride_id
// (an open ride's row is updated in place, so a ride in progress survives a restart); commands
// are upserted by command_id; all other records are appended.
struct Batch {
  std::int64_t now_us = 0;  // created_us of the outbox entries queued by this batch
  std::vector<PendingRow<TelemetryRow>> telemetry;
  std::vector<PendingRow<RideRow>> rides;
  std::vector<PendingRow<FaultEventRow>> faults;
  std::vector<PendingRow<PackSnapshotRow>> packs;
  std::vector<PendingRow<LockEventRow>> locks;
  std::vector<PendingRow<AlarmRow>> alarms;
  std::vector<PendingRow<ZoneEventRow>> zone_events;
  std::vector<PendingRow<CommandResultRow>> command_results;
  std::vector<CommandJournalRow> commands;
  std::vector<UplinkMessage> messages;
  std::vector<std::pair<std::string, std::string>> meta;  // keys "storage.*" are reserved

  std::size_t size() const;
  bool empty() const { return size() == 0; }
  void clear();
};

// A file that is not a fleetgw store (missing, not SQLite, or SQLite without fleetgw's tables),
// from a read-only open.
class NotAStoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// What a successful write() stored (a failed one returns its Status instead).
struct Written {
  // Sequence numbers assigned by this batch: [first_seq, end_seq), contiguous; empty when the
  // batch queued nothing.
  std::uint64_t first_seq = 0;
  std::uint64_t end_seq = 0;
  std::size_t records = 0;  // table rows written
  std::optional<EvictionPass> eviction;
};

struct OutboxDepth {
  int priority = 0;
  std::uint64_t entries = 0;
  std::uint64_t payload_bytes = 0;
  friend bool operator==(const OutboxDepth&, const OutboxDepth&) = default;
};

struct EvictionCounter {
  std::string table;
  std::uint64_t rows = 0;
  std::uint64_t passes = 0;
  std::optional<std::int64_t> last_us;
};

struct Stats {
  std::string path;
  int schema_version = 0;
  std::vector<std::pair<std::string, std::uint64_t>> table_rows;  // table name -> row count
  std::vector<OutboxDepth> outbox;                                // by priority, ascending
  std::uint64_t outbox_in_flight = 0;
  std::optional<std::uint64_t> oldest_unsent_seq;
  std::optional<std::int64_t> oldest_unsent_us;
  std::optional<std::string> oldest_unsent_kind;
  std::uint64_t file_bytes = 0;  // main database file on disk
  std::uint64_t wal_bytes = 0;   // -wal file on disk
  std::uint64_t page_size = 0;
  std::uint64_t page_count = 0;
  std::uint64_t freelist_pages = 0;
  std::uint64_t live_bytes = 0;    // what the budget is measured against
  std::uint64_t budget_bytes = 0;  // effective budget (after clamping)
  std::uint64_t configured_budget_bytes = 0;
  std::uint64_t wal_allowance_bytes = 0;  // part of the budget kept for the WAL
  std::uint64_t reserve_bytes = 0;        // part kept for records that are never evicted
  std::uint64_t next_seq = 0;
  std::vector<EvictionCounter> evictions;
  nlohmann::json to_json() const;
};

using RowWriter = std::function<void(const nlohmann::json& row)>;

class Store {
 public:
  // Largest accepted uplink payload; bigger ones are a gateway bug, not data.
  static constexpr std::size_t kMaxPayloadBytes = 1 << 20;

  explicit Store(StoreOptions options);
  Store(Store&&) noexcept;
  Store& operator=(Store&&) noexcept;
  ~Store();

  Result<Written> write(const Batch& batch);

  // Outbox, for the uplink.
  // Up to `limit` entries, in (priority, seq) order, not in flight, whose payloads total at most
  // `max_bytes` -- except that the first entry is always returned so a single large payload
  // cannot block the queue. The returned entries become in flight.
  std::vector<OutboxRow> peek_outbox(std::size_t limit, std::size_t max_bytes);
  // Same, leaving out every entry whose kind is in `skip_kinds` (the uplink's kinds the broker
  // refuses, waiting for their retry): filtered in the query, so a backlog of a refused kind
  // costs no reads and does not hold back the kinds behind it.
  std::vector<OutboxRow> peek_outbox(std::size_t limit, std::size_t max_bytes,
                                       std::span<const OutboxKind> skip_kinds);
  // Deletes the acknowledged entries (only those); returns how many rows existed and were
  // deleted (an entry evicted meanwhile is not counted). Clears their in-flight mark. On a
  // disk error nothing is deleted (the entries are sent again later) and its Status is
  // returned (kFull, kIo, kOther), the failure recorded in health(). A read-only store deletes
  // nothing and returns kInvalid (not recorded in health()).
  Result<std::size_t> ack(std::span<const std::uint64_t> seqs);
  // Makes in-flight entries eligible for peek_outbox() again.
  void release(std::span<const std::uint64_t> seqs);
  void release_all();
  std::size_t in_flight() const;
  std::vector<OutboxDepth> outbox_depth();
  // Calls `visit` with every outbox entry of `kind`, in flight or not, in seq order (the
  // campaign service recomputes each campaign's bytes in the store from them at start-up).
  // Returns how many; never throws (an error is recorded in health() and ends the walk).
  std::uint64_t visit_outbox(OutboxKind kind, const std::function<void(const OutboxRow&)>& visit);
  std::optional<std::int64_t> oldest_unsent_us();
  std::uint64_t next_seq() const;
  // Random identifier (a UUID) created with the store and kept in its meta table
  // ('storage.store_id'): sequences are unique per store_id. Empty only for a read-only open of
  // a store that never had one.
  const std::string& store_id() const;

  // Health as `fleetgw status` reports it (storage/health.h).
  StorageHealth health() const;
  // Asks for a WAL checkpoint when the WAL holds half its allowance or more; cheap otherwise
  // (no syscall). The checkpoint runs on the store's background checkpointer
  // (storage/checkpointer.h) and this call never waits for it. Returns true when a checkpoint
  // was requested. Never throws.
  bool checkpoint_if_due();
  // What the background checkpointer did so far (all zero when read-only).
  CheckpointCounters checkpoint_counters() const;
  // The budget actually enforced (clamped to the file system at open), 0 = unlimited.
  std::uint64_t effective_budget() const;
  bool read_only() const;

  // State the gateway restores at start-up.
  std::vector<RideRow> open_rides();
  std::optional<RideRow> ride(std::string_view ride_id);
  // Telemetry samples with from_us <= ts_us <= to_us, in time order (`fleetgw ride plot`).
  std::vector<TelemetryRow> telemetry_between(std::int64_t from_us, std::int64_t to_us);
  std::optional<CommandJournalRow> command(std::string_view command_id);
  // True when the command id was recorded and has not expired at now_us.
  bool command_seen(std::string_view command_id, std::int64_t now_us);
  // Forgets seen command ids (and finished journal entries) that expired before now_us.
  std::size_t purge_expired_commands(std::int64_t now_us);
  std::optional<std::string> meta(std::string_view key);

  // Technician tools.
  Stats stats();
  // Calls `write_row` with one JSON object per row of `table` whose time column is >= since_us
  // (tables without a time column ignore since_us), in insertion order. *_json columns are
  // embedded as JSON, blobs as lowercase hex. Unknown tables throw std::invalid_argument
  // listing the known ones. Returns the number of rows.
  std::uint64_t export_table(std::string_view table, std::int64_t since_us,
                             const RowWriter& write_row);
  // Same, as JSON lines.
  std::uint64_t export_table(std::string_view table, std::int64_t since_us, std::ostream& out);
  static std::span<const std::string_view> exportable_tables();
  // The columns of `table` in schema order (the members of export_table's rows), for writers
  // that need them before the first row (CSV headers). Unknown tables throw as export_table.
  std::vector<std::string> export_columns(std::string_view table);
  // Newest first, for `fleetgw db rides|faults|commands|alarms`: calls `write_row` with one JSON
  // object per row (columns as export_table) of the listing, at most `limit` rows (0: all),
  // only rows at or after `since_us`. Listings (order and time filter):
  //   "rides"    rides by start_us;
  //   "faults"   fault_events by their event time `at_us` (last_seen_us for a cleared event,
  //              first_seen_us otherwise), an extra column;
  //   "alarms"   alarms by ts_us;
  //   "commands" one row per command: the journal (commands) joined with its result
  //              (command_results), plus results whose journal entry was purged; columns
  //              command_id, at_us (received_us, else the result's ts_us), received_us,
  //              state (journal), result_us, result, reason, final_state, duration_ms,
  //              expires_at_us (NULL where unknown).
  // Unknown listings throw std::invalid_argument listing the known ones. Returns the rows.
  std::uint64_t list_recent(std::string_view listing, std::int64_t since_us, std::uint64_t limit,
                            const RowWriter& write_row);
  static std::span<const std::string_view> listings();

  // Maintenance and diagnostics.
  std::string integrity_check();  // "ok" or SQLite's list of problems
  std::uint64_t live_bytes();
  int synchronous_mode();  // PRAGMA synchronous of the connection: 1 NORMAL, 2 FULL
  const std::string& path() const;
  // Where a corrupt database found at open was moved, if one was.
  const std::optional<std::string>& moved_aside_path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fleetgw::storage
