// Store::Impl: the state behind storage::Store, shared by the files that implement it, one idea
// each (internal to fleetgw_storage; include only from storage/store*.cc and outbox.cc):
//   store_open.cc    opening: lock file, header check, move-aside, read-only open, pragmas
//   store_write.cc   batch validation and the one-transaction write, SQLITE_FULL retry
//   store_budget.cc  disk budget (WAL and reserve included), eviction, clamp, checkpoints
//   checkpointer.cc  the background thread that runs checkpoint_if_due()'s checkpoints
//   outbox.cc        outbox queue (peek/ack/release) and the start-up restore queries
//   store_export.cc  technician tools: stats and table export
//   store_telemetry.cc  the telemetry of a time window (fleetgw ride plot)
//   store.cc         Store's lifecycle, health and small accessors
//
// Contract: Impl is used from one thread (the checkpointer's thread shares none of its state).
// Members marked "health" are updated by every write attempt (write(), ack(), purge...) through
// record_success()/record_failure().
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <unordered_set>

#include "storage/checkpointer.h"
#include "storage/health.h"
#include "storage/rate_limited_log.h"
#include "storage/sqlite.h"
#include "storage/store.h"

namespace spdlog {
class logger;
}

namespace fleetgw::storage {

// Reserved meta key of the persisted sequence counter (the next number to hand out).
inline constexpr std::string_view kNextSeqKey = "storage.next_seq";
// Reserved meta key of the store's random identifier (Store::store_id()).
inline constexpr std::string_view kStoreIdKey = "storage.store_id";
inline constexpr int kEvictionReportPriority = records::default_priority(OutboxKind::kEvictionReport);

// flock()-based exclusive lock on "<db>.lock": one writer per database, across processes.
// A separate file is used because closing any descriptor of the database file itself would
// drop SQLite's POSIX locks (fcntl semantics).
class LockFile {
 public:
  explicit LockFile(const std::string& path);
  LockFile(LockFile&& other) noexcept;
  LockFile& operator=(LockFile&&) = delete;
  LockFile(const LockFile&) = delete;
  LockFile& operator=(const LockFile&) = delete;
  ~LockFile();

 private:
  int fd_ = -1;
};

// The budget split (storage/store.h, "Disk budget"), all in bytes; 0 budget = unlimited.
struct BudgetPlan {
  std::uint64_t configured = 0;
  std::uint64_t effective = 0;      // clamped to the file system
  std::uint64_t wal_allowance = 0;  // WAL file, bounded by checkpoints
  std::uint64_t shm_allowance = 0;  // -shm file
  std::uint64_t reserve = 0;        // for records that are never evicted
  std::uint64_t wal_pages = 0;      // WAL frames at which write() itself checkpoints
  // Live database pages above which telemetry/pack snapshots are evicted.
  std::uint64_t evictable_limit() const;
  // Live database pages above which the store is over budget even with nothing evictable.
  std::uint64_t data_limit() const;
};

// Splits `effective` into WAL, shm, reserve and data (pure; tested directly).
BudgetPlan plan_budget(std::uint64_t configured, std::uint64_t effective, std::uint64_t page_size,
                       int wal_pages_override);
// The budget clamped to what the file system holding `db_path` can give the store: its free
// space plus what the store's files already occupy, minus a 5 % margin. nullopt when statvfs
// fails (the budget is then left as configured).
std::optional<std::uint64_t> disk_capacity_for(Env& env, const std::string& db_path);

// The Status of a failed SQLite step (kFull, kIo, kInvalid, kOther), with SQLite's message.
Status to_status(const std::exception& e);

struct Store::Impl {
  StoreOptions options;
  std::shared_ptr<spdlog::logger> log;
  std::optional<LockFile> lock;  // absent when read-only
  std::optional<std::string> moved_aside;
  Database db;
  std::uint64_t next_seq = 1;
  std::string store_id;
  std::unordered_set<std::uint64_t> in_flight;
  bool budget_exhausted_logged = false;
  BudgetPlan budget;
  std::uint64_t page_size = 4096;
  std::uint64_t wal_frames = 0;  // frames in the WAL after the last commit (wal hook)
  // health
  StorageHealth health;
  RateLimitedLog error_log;
  std::optional<std::chrono::steady_clock::time_point> last_recovery_logged;
  // Evictions forced by a full disk happen at every retry: the first is logged, later ones are
  // summed into one line per 10 s.
  struct {
    std::optional<std::chrono::steady_clock::time_point> last_logged;
    std::uint64_t rows = 0;
    std::uint64_t passes = 0;
  } disk_full_evictions;
  // Background checkpoints (absent when read-only or in memory). Declared after `db` so it
  // stops and closes its connection before the store's own connection closes.
  std::optional<Checkpointer> checkpointer;

  explicit Impl(StoreOptions opts);

  // store_open.cc
  Database open_database();
  Database open_read_only();
  void move_aside(const std::string& problem);
  void configure();
  void load_next_seq();
  void load_store_id(bool create);
  void plan_disk_budget();
  static int on_wal_commit(void* impl, sqlite3* db, const char* name, int frames);

  // store_budget.cc
  std::uint64_t live_bytes();
  std::optional<EvictionPass> enforce_budget(std::int64_t now_us, Statement& outbox,
                                               std::uint64_t& seq);
  // After SQLITE_FULL: restarts the WAL and evicts the oldest telemetry (then pack snapshots)
  // in its own transaction, without giving the pages back to the file system (the retry reuses
  // them). Returns the rows evicted (0: nothing could be freed).
  std::uint64_t evict_for_space(std::int64_t now_us, int attempt);
  bool checkpoint(int mode);  // SQLITE_CHECKPOINT_*; false on failure/busy, never throws

  // store_write.cc
  Result<Written> write(const Batch& b);
  Written write_once(const Batch& b);  // throws; write() turns the exception into a Status
  void enqueue(Statement& st, OutboxKind kind, int priority, std::span<const std::uint8_t> payload,
               std::optional<std::int64_t> source_id, std::int64_t now_us, std::uint64_t& seq);

  // store.cc
  std::size_t purge_expired_commands(std::int64_t now_us);
  void record_success();
  void record_failure(const Status& error, std::string_view what);
};

}  // namespace fleetgw::storage
