// Checkpointer: runs the store's WAL checkpoints on a background thread, so the fsyncs of a
// checkpoint (5-28 ms measured) never block the thread that writes (the gateway's event loop).
//
// Contract:
// - Owns one thread, started through the Env it is given (env/env.h), and that thread's OWN SQLite connection to the database file
//   (SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, busy_timeout set; it never writes rows).
//   The constructor opens the connection and throws SqliteError when it cannot.
// - request() asks for one checkpoint and returns at once: it never waits for a checkpoint in
//   progress. Requests made while one is pending or running are coalesced into the next one.
// - Checkpoints are SQLITE_CHECKPOINT_PASSIVE only: they never wait for, nor block, readers or
//   the writer. A checkpoint that a reader keeps from copying every frame counts as partial;
//   the next request tries again. After a PASSIVE checkpoint that copied every frame, the
//   writer's next commit restarts the WAL from its beginning (and its journal_size_limit
//   truncates a WAL that grew beyond it).
// - Errors are counted and logged (rate-limited, storage/rate_limited_log.h), never thrown.
// - The destructor stops the thread (a pending request is dropped, a running checkpoint
//   finishes) and joins it before the connection closes. Destroy the Checkpointer before the
//   store's own connection, so that one closes last and removes the WAL.
// - wait_until_idle() blocks until no checkpoint is pending or running (the store's inline
//   checkpoints use it: two connections cannot checkpoint at once).
// - Shared with the thread: the request and running flags (under a mutex, with condition
//   variables) and the counters (std::atomic). Every member function may be called from any one
//   other thread.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "env/env.h"
#include "storage/health.h"
#include "storage/rate_limited_log.h"
#include "storage/sqlite.h"

namespace spdlog {
class logger;
}

namespace fleetgw::storage {

class Checkpointer {
 public:
  Checkpointer(const std::string& path, std::shared_ptr<spdlog::logger> log,
               Env& env = Env::system());
  Checkpointer(const Checkpointer&) = delete;
  Checkpointer& operator=(const Checkpointer&) = delete;
  ~Checkpointer();

  void request();
  // Blocks until no checkpoint is pending or running. For the store's own inline checkpoints
  // (the safety net at the whole WAL allowance, the disk-full path): only one connection can
  // checkpoint at a time, and the store's thread, waiting here, appends no frames meanwhile.
  void wait_until_idle();
  CheckpointCounters counters() const;

 private:
  void run(std::stop_token stop);
  void checkpoint_once();  // on worker_ only

  // Used only by worker_ once it runs.
  Database db_;
  std::shared_ptr<spdlog::logger> log_;
  RateLimitedLog errors_;    // single-threaded: the worker's own
  bool wal_opened_ = false;  // the connection has read the WAL (see checkpoint_once)
  // Shared.
  std::mutex mutex_;
  std::condition_variable_any wake_;  // pending_ was set, or stop was requested
  std::condition_variable idle_;      // running_ and pending_ both became false
  bool pending_ = false;              // guarded by mutex_
  bool running_ = false;              // guarded by mutex_
  std::atomic<std::uint64_t> requested_{0};
  std::atomic<std::uint64_t> completed_{0};
  std::atomic<std::uint64_t> partial_{0};
  std::atomic<std::uint64_t> failed_{0};
  std::jthread worker_;  // last: starts after, and stops before, everything above
};

}  // namespace fleetgw::storage
