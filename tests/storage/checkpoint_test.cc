// Background WAL checkpoints (storage/checkpointer.h): checkpoint_if_due() only asks the
// store's checkpointer thread, which keeps the WAL bounded on its own connection; a reader
// holding an old snapshot neither blocks the writer nor checkpoint_if_due(), and the WAL is
// checkpointed (and cut back to its allowance) once the reader is gone; the store closes
// cleanly with a request pending. Real SQLite files; waits poll with a deadline.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>
#include <vector>

#include "env/env.h"
#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

// A small WAL allowance (64 frames of 4 KiB): a few batches fill half of it.
constexpr int kWalPages = 64;

Batch telemetry_batch(std::int64_t& t, int n) {
  Batch b;
  b.now_us = t;
  for (int i = 0; i < n; ++i, t += 1000) {
    b.telemetry.push_back({telemetry_at(t), Bytes(64, static_cast<std::uint8_t>(i))});
  }
  return b;
}

std::uint64_t wal_size(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path + "-wal", ec);
  return ec ? 0 : size;
}

bool wait_until(const std::function<bool()>& condition,
                std::chrono::steady_clock::duration timeout = 10s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

std::int64_t telemetry_rows(const std::string& path) {
  Database db(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX);
  return db.query_int64("SELECT count(*) FROM telemetry").value_or(-1);
}

TEST(Checkpointer, KeepsTheWalBoundedWhenAskedOnlyThroughCheckpointIfDue) {
  TempDir dir;
  const std::string path = dir.file("bounded.db");
  Store store(StoreOptions{.path = path, .wal_autocheckpoint_pages = kWalPages});
  const std::uint64_t allowance = store.stats().wal_allowance_bytes;
  std::int64_t t = 1;
  std::uint64_t worst_wal = 0;
  int requests = 0;
  for (int batch = 0; batch < 150; ++batch) {  // ~15x the WAL allowance
    ASSERT_TRUE(store.write(telemetry_batch(t, 40)).ok());
    worst_wal = std::max(worst_wal, wal_size(path));
    const auto before = store.checkpoint_counters().completed;
    if (!store.checkpoint_if_due()) continue;
    ++requests;
    // The worker copies the WAL into the database on its own; the store's thread only waits
    // here so that the next write can restart the WAL (as the event loop's next flush would).
    ASSERT_TRUE(wait_until([&] { return store.checkpoint_counters().completed > before; }))
        << "the background checkpointer never completed the checkpoint asked for";
  }
  EXPECT_GT(requests, 5) << "the WAL reached half its allowance several times";
  EXPECT_EQ(store.checkpoint_counters().failed, 0u);
  // Restarted at half the allowance, the WAL never grew to the whole of it (where write()
  // itself would have checkpointed).
  EXPECT_LE(worst_wal, allowance);
  EXPECT_GT(worst_wal, allowance / 4) << "the WAL was used";
  EXPECT_EQ(telemetry_rows(path), 150 * 40);
}

TEST(Checkpointer, AReaderHoldingOldFramesBlocksNeitherWritesNorRequests) {
  TempDir dir;
  const std::string path = dir.file("reader.db");
  Store store(StoreOptions{.path = path, .wal_autocheckpoint_pages = kWalPages});
  const std::uint64_t allowance = store.stats().wal_allowance_bytes;
  std::int64_t t = 1;
  ASSERT_TRUE(store.write(telemetry_batch(t, 40)).ok());

  // A technician's reader on a third connection keeps its snapshot: no checkpoint can copy
  // the frames written after it, and the WAL cannot restart.
  Database reader(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX);
  reader.exec("BEGIN");
  EXPECT_EQ(reader.query_int64("SELECT count(*) FROM telemetry"), 40);

  int requests = 0;
  for (int batch = 0; batch < 60; ++batch) {
    ASSERT_TRUE(store.write(telemetry_batch(t, 40)).ok()) << "batch " << batch;
    if (store.checkpoint_if_due()) ++requests;
  }
  EXPECT_GT(wal_size(path), allowance) << "the reader kept the WAL from restarting";
  // Every write left the WAL over half its allowance, so the event loop kept asking; how long
  // a request takes (it only signals the worker: microseconds, not a checkpoint's fsyncs) is
  // a timing goal: bench/bench_storage.cc BM_CheckpointRequest reports it.
  EXPECT_GT(requests, 0);
  ASSERT_TRUE(wait_until([&] { return store.checkpoint_counters().partial > 0; }))
      << "the worker tried and was cut short by the reader";
  EXPECT_EQ(store.checkpoint_counters().failed, 0u);

  reader.exec("COMMIT");  // the reader is gone
  // The event loop goes on writing and asking; the WAL is checkpointed (by the worker, or by
  // write() itself at the whole allowance), the next commit restarts it and
  // journal_size_limit cuts the file back to its allowance.
  int writes = 0;
  EXPECT_TRUE(wait_until([&] {
    ++writes;
    if (!store.write(telemetry_batch(t, 1)).ok()) return false;
    store.checkpoint_if_due();
    return wal_size(path) <= allowance;
  })) << "the WAL was not checkpointed once the reader was gone";
  EXPECT_EQ(store.checkpoint_counters().failed, 0u);
  EXPECT_EQ(telemetry_rows(path), 61 * 40 + writes);
}

TEST(Checkpointer, StoreClosesCleanlyWithARequestPending) {
  TempDir dir;
  const std::string path = dir.file("close.db");
  std::int64_t t = 1;
  for (int round = 1; round <= 10; ++round) {
    {
      Store store(StoreOptions{.path = path, .wal_autocheckpoint_pages = kWalPages});
      while (!store.checkpoint_if_due()) ASSERT_TRUE(store.write(telemetry_batch(t, 40)).ok());
      // Destroyed at once: the worker may be idle, woken or mid-checkpoint.
    }
    // The store's own connection closed last: it checkpointed and removed the WAL, which is
    // how the read-only tools know that nobody is writing.
    EXPECT_FALSE(fs::exists(path + "-wal")) << "round " << round;
    EXPECT_EQ(Store(StoreOptions{.path = path}).integrity_check(), "ok") << "round " << round;
    EXPECT_FALSE(fs::exists(path + "-wal")) << "round " << round;
  }
  EXPECT_EQ(telemetry_rows(path), (t - 1) / 1000);
}

TEST(Checkpointer, ReadOnlyStoreHasNone) {
  TempDir dir;
  const std::string path = dir.file("ro.db");
  { Store writer(StoreOptions{.path = path}); }
  Store reader(StoreOptions{.path = path, .read_only = true});
  EXPECT_FALSE(reader.checkpoint_if_due());
  EXPECT_EQ(reader.checkpoint_counters().requested, 0u);
}

// The real machine, except that it counts and names the threads it starts and can refuse
// renames: what a test needs to see that the store goes through its Env.
class CountingEnv final : public Env {
 public:
  Micros wall_now() const override { return Env::system().wall_now(); }
  SteadyTime steady_now() const override { return Env::system().steady_now(); }
  std::jthread start_thread(std::string_view name,
                            std::function<void(std::stop_token)> fn) override {
    names.emplace_back(name);
    return Env::start_thread(name, std::move(fn));
  }
  std::error_code rename_file(const fs::path& from, const fs::path& to) override {
    if (refuse_renames) return std::make_error_code(std::errc::read_only_file_system);
    return Env::rename_file(from, to);
  }
  std::vector<std::string> names;  // written at construction only, before any thread runs
  bool refuse_renames = false;
};

TEST(Checkpointer, ItsThreadIsStartedThroughTheStoresEnv) {
  TempDir dir;
  const std::string path = dir.file("env.db");
  CountingEnv env;
  {
    Store store(StoreOptions{.path = path, .wal_autocheckpoint_pages = kWalPages, .env = &env});
    ASSERT_EQ(env.names, std::vector<std::string>{"fleetgw-ckpt"});
    std::int64_t t = 1;
    while (!store.checkpoint_if_due()) ASSERT_TRUE(store.write(telemetry_batch(t, 40)).ok());
    // The thread the Env started is the one that checkpoints.
    ASSERT_TRUE(wait_until([&] { return store.checkpoint_counters().completed > 0; }));
  }
  // A read-only store starts no thread at all.
  Store reader(StoreOptions{.path = path, .read_only = true, .env = &env});
  EXPECT_EQ(env.names.size(), 1u);
}

TEST(Checkpointer, ACorruptFileIsMovedAsideThroughTheEnvAndItsFailureNamesThePaths) {
  TempDir dir;
  const std::string path = dir.file("bad.db");
  {
    std::ofstream out(path, std::ios::binary);
    out << std::string(8192, 'z');
  }
  CountingEnv env;
  env.refuse_renames = true;
  try {
    Store store(StoreOptions{.path = path, .env = &env});
    FAIL() << "a store whose corrupt file cannot be moved aside must not start";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("could not be moved aside"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(path)) << "the bad file stays where it was";
}

}  // namespace
}  // namespace fleetgw::storage
