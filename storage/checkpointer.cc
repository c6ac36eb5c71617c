// Background WAL checkpoints (storage/checkpointer.h).
#include "storage/checkpointer.h"

#include <spdlog/spdlog.h>

#include <utility>

#include "storage/rate_limited_log.h"

namespace fleetgw::storage {

Checkpointer::Checkpointer(const std::string& path, std::shared_ptr<spdlog::logger> log,
                           Env& env)
    : db_(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX),
      log_(log),
      errors_(std::move(log), std::chrono::seconds(10), env),
      worker_(env.start_thread("fleetgw-ckpt",
                               [this](std::stop_token stop) { run(std::move(stop)); })) {}

Checkpointer::~Checkpointer() {
  worker_.request_stop();  // wakes wait() below through the stop token
  if (worker_.joinable()) worker_.join();
}

void Checkpointer::request() {
  requested_.fetch_add(1, std::memory_order_relaxed);
  {
    std::lock_guard lock(mutex_);
    if (pending_) return;  // coalesced with the one already asked for
    pending_ = true;
  }
  wake_.notify_one();
}

void Checkpointer::wait_until_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] { return !pending_ && !running_; });
}

CheckpointCounters Checkpointer::counters() const {
  return {requested_.load(std::memory_order_relaxed), completed_.load(std::memory_order_relaxed),
          partial_.load(std::memory_order_relaxed), failed_.load(std::memory_order_relaxed)};
}

void Checkpointer::run(std::stop_token stop) {
  // The schema lock and the first read of a fresh connection may meet the writer's commit.
  sqlite3_busy_timeout(db_.handle(), 5000);
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      if (!wake_.wait(lock, stop, [this] { return pending_; })) {
        pending_ = false;  // stop requested: a pending request is dropped
        lock.unlock();
        idle_.notify_all();
        return;
      }
      pending_ = false;
      running_ = true;
    }
    checkpoint_once();
    {
      std::lock_guard lock(mutex_);
      running_ = false;
    }
    idle_.notify_all();
  }
}

void Checkpointer::checkpoint_once() {
  // A connection opens the WAL on its first read; until then a checkpoint does nothing and
  // reports -1 frames. Any read opens it (and it stays open).
  int rc = wal_opened_ ? SQLITE_OK
                       : sqlite3_exec(db_.handle(), "SELECT count(*) FROM sqlite_master", nullptr,
                                      nullptr, nullptr);
  int log_frames = -1, copied = -1;
  if ((rc & 0xff) == SQLITE_OK) {
    rc = sqlite3_wal_checkpoint_v2(db_.handle(), nullptr, SQLITE_CHECKPOINT_PASSIVE, &log_frames,
                                   &copied);
  }
  const int primary = rc & 0xff;  // extended result codes are on
  wal_opened_ = primary == SQLITE_OK && log_frames >= 0;
  if (primary == SQLITE_OK && log_frames < 0) {
    // Not in WAL mode (cannot happen: the store put the file in WAL mode before this ran).
    failed_.fetch_add(1, std::memory_order_relaxed);
    errors_.report(std::string("storage: background WAL checkpoint of '") + db_.path() +
                   "' found no WAL");
  } else if (primary == SQLITE_OK && log_frames == copied) {
    completed_.fetch_add(1, std::memory_order_relaxed);
  } else if (primary == SQLITE_OK || primary == SQLITE_BUSY) {
    partial_.fetch_add(1, std::memory_order_relaxed);  // a reader holds old frames: retried
  } else {
    failed_.fetch_add(1, std::memory_order_relaxed);
    errors_.report(std::string("storage: background WAL checkpoint of '") + db_.path() +
                   "' failed: " + sqlite3_errstr(rc) + " (" + sqlite3_errmsg(db_.handle()) + ")");
  }
}

}  // namespace fleetgw::storage
