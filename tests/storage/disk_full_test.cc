// The disk budget covers the WAL and keeps a reserve for records that are never evicted; a
// full disk (SQLITE_FULL) evicts telemetry and retries, and is reported in health() without
// throwing; a budget bigger than the file system is clamped with a warning.
// A "disk" exactly as big as the budget is simulated with StoreOptions::max_page_count, which
// makes SQLite report SQLITE_FULL exactly as a full file system does.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <map>
#include <sstream>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage/store_impl.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;
namespace fs = std::filesystem;

std::uint64_t files_on_disk(const std::string& path) {
  std::uint64_t total = 0;
  for (std::string_view suffix : {"", "-wal", "-shm"}) {
    std::error_code ec;
    const auto size = fs::file_size(path + std::string(suffix), ec);
    if (!ec) total += size;
  }
  return total;
}

Batch telemetry_batch(std::int64_t& t, int n) {
  Batch b;
  b.now_us = t;
  for (int i = 0; i < n; ++i, t += 1000) {
    b.telemetry.push_back({telemetry_at(t), Bytes(64, static_cast<std::uint8_t>(i))});
  }
  return b;
}

Batch precious_batch(int k) {
  Batch b;
  b.now_us = k;
  b.faults.push_back({fault_at(k, k), payload_of("fault")});
  b.command_results.push_back({command_result("c" + std::to_string(k), k), payload_of("cmd")});
  b.commands.push_back({"c" + std::to_string(k), k, "succeeded", k + 1'000'000});
  return b;
}

TEST(BudgetPlan, WalShmReserveAndDataAddUpToTheBudget) {
  for (std::uint64_t budget : {256ull << 10, 2ull << 20, 64ull << 20, 256ull << 20}) {
    const BudgetPlan p = plan_budget(budget, budget, 4096, 0);
    EXPECT_EQ(p.evictable_limit() + p.reserve + p.wal_allowance + p.shm_allowance, budget)
        << budget;
    EXPECT_GT(p.wal_allowance, 0u);
    EXPECT_LE(p.wal_allowance, 4u << 20);
    EXPECT_GT(p.reserve, 0u) << "records that are never evicted always have room";
    EXPECT_LT(p.evictable_limit(), p.data_limit());
    EXPECT_GE(p.wal_pages * 4096, p.wal_allowance / 2);
  }
  const BudgetPlan unlimited = plan_budget(0, 0, 4096, 0);
  EXPECT_EQ(unlimited.reserve, 0u);
  EXPECT_GT(unlimited.evictable_limit(), 1ull << 60);
}

TEST(DiskBudget, FilesOnDiskIncludingWalStayWithinTheBudget) {
  TempDir dir;
  const std::string path = dir.file("wal.db");
  constexpr std::uint64_t kBudget = 2 << 20;
  Store store(StoreOptions{.path = path, .max_bytes = kBudget});
  std::int64_t t = 1;
  std::uint64_t worst = 0;
  for (int batch = 0; batch < 200; ++batch) {  // ~6x the budget
    ASSERT_TRUE(store.write(telemetry_batch(t, 500)).ok());
    store.checkpoint_if_due();  // what the recorder does after each flush
    worst = std::max(worst, files_on_disk(path));
  }
  EXPECT_LE(worst, kBudget) << "database + WAL + shm, measured after every batch";
  EXPECT_GT(worst, kBudget / 2) << "the budget is used, not wasted";
  // The WAL stays bounded: checkpoints run on the store's background thread, so on a loaded
  // machine one may lag a commit or two behind (each batch here is ~40 % of the allowance)
  // before write() checkpoints inline at the whole allowance; the budget above is the promise.
  EXPECT_LE(fs::file_size(path + "-wal"), 3 * store.stats().wal_allowance_bytes);
}

TEST(DiskBudget, WalIsBoundedEvenWithoutCheckpointCalls) {
  TempDir dir;
  const std::string path = dir.file("wal2.db");
  constexpr std::uint64_t kBudget = 4 << 20;
  Store store(StoreOptions{.path = path, .max_bytes = kBudget});
  std::int64_t t = 1;
  std::uint64_t worst_wal = 0;
  for (int batch = 0; batch < 100; ++batch) {
    ASSERT_TRUE(store.write(telemetry_batch(t, 500)).ok());
    std::error_code ec;
    worst_wal = std::max<std::uint64_t>(worst_wal, fs::file_size(path + "-wal", ec));
  }
  const auto allowance = store.stats().wal_allowance_bytes;
  // write() checkpoints at the whole allowance; one batch's frames (here 500 samples plus an
  // eviction pass) may come on top.
  EXPECT_LE(worst_wal, 2 * allowance);
  EXPECT_GT(worst_wal, 0u);
}

TEST(DiskBudget, ReserveLetsPreciousRecordsInWhenTelemetryFilledTheDisk) {
  TempDir dir;
  const std::string path = dir.file("reserve.db");
  constexpr std::uint64_t kBudget = 1 << 20;
  // The disk holds exactly the budget's data part: without a reserve, telemetry would fill it.
  const BudgetPlan plan = plan_budget(kBudget, kBudget, 4096, 0);
  Store store(
      StoreOptions{.path = path, .max_bytes = kBudget, .max_page_count = plan.data_limit() / 4096});
  std::int64_t t = 1;
  for (int round = 0; round < 60; ++round) {  // ~5x the budget in telemetry
    ASSERT_TRUE(store.write(telemetry_batch(t, 300)).ok()) << round;
  }
  ASSERT_GT(counts(store)["telemetry"], 1000u) << "telemetry did fill the budget";
  // Precious records worth most of the reserve, in one go, with no telemetry to make room.
  Batch precious;
  for (int k = 0; k < 200; ++k) {
    precious.faults.push_back({fault_at(k, k), Bytes(150, 1)});
    precious.command_results.push_back({command_result("r" + std::to_string(k), k), Bytes(50, 2)});
  }
  const auto r = store.write(precious);
  ASSERT_TRUE(r.ok()) << r.status().message;
  EXPECT_EQ(store.health().full_recoveries, 0u) << "the reserve held: no SQLITE_FULL at all";
  EXPECT_FALSE(store.health().failing);
  EXPECT_EQ(counts(store)["fault_events"], 200u);
}

TEST(DiskFull, EvictsTelemetryAndRetriesSoEveryWriteSucceeds) {
  TempDir dir;
  const std::string path = dir.file("full.db");
  // No budget at all: only the "disk" (256 pages = 1 MB) limits the store.
  Store store(StoreOptions{.path = path, .max_page_count = 256});
  std::int64_t t = 1;
  int k = 0;
  for (int round = 0; round < 80; ++round) {  // ~4x what the disk holds
    auto b = telemetry_batch(t, 300);
    const auto p = precious_batch(++k);
    for (const auto& f : p.faults) b.faults.push_back(f);
    for (const auto& c : p.command_results) b.command_results.push_back(c);
    for (const auto& c : p.commands) b.commands.push_back(c);
    const auto r = store.write(b);
    ASSERT_TRUE(r.ok()) << "round " << round << ": " << r.status().message;
  }
  const auto h = store.health();
  EXPECT_GT(h.full_recoveries, 0u) << "the disk did fill up";
  EXPECT_FALSE(h.failing);
  EXPECT_EQ(h.failed_writes, 0u);
  auto c = counts(store);
  EXPECT_EQ(c["fault_events"], 80u) << "never evicted";
  EXPECT_EQ(c["command_results"], 80u);
  EXPECT_EQ(c["commands"], 80u);
  EXPECT_LT(c["telemetry"], 80u * 300u) << "the oldest telemetry made room";
  std::map<std::string, EvictionCounter> ev;
  for (const auto& e : store.stats().evictions) ev[e.table] = e;
  EXPECT_EQ(ev["telemetry"].rows + c["telemetry"], 80u * 300u) << "every eviction is counted";
  EXPECT_EQ(store.integrity_check(), "ok");
}

TEST(DiskFull, NothingEvictableFailsWithoutThrowingAndRecoversWhenSpaceReturns) {
  TempDir dir;
  const std::string path = dir.file("full2.db");
  ManualEnv env;  // failing_since_us comes from its wall clock, not the machine's
  std::int64_t wall = env.wall_now().count();
  Store store(StoreOptions{.path = path, .max_page_count = 64, .env = &env});
  int k = 0;
  Status last;
  for (; k < 5000; ++k) {
    Batch b;
    b.now_us = k;
    b.faults.push_back({fault_at(k, k), Bytes(200, 7)});
    const auto r = store.write(b);
    if (!r.ok()) {
      last = r.status();
      break;
    }
  }
  ASSERT_LT(k, 5000) << "64 pages must fill up";
  EXPECT_EQ(last.code, StatusCode::kFull);
  auto h = store.health();
  EXPECT_TRUE(h.failing);
  EXPECT_EQ(h.last_error, "disk full (SQLITE_FULL)");
  EXPECT_EQ(h.failing_since_us, wall);
  EXPECT_EQ(h.failed_writes, 1u);
  const auto faults_before = counts(store)["fault_events"];
  EXPECT_EQ(faults_before, static_cast<std::uint64_t>(k)) << "the failed batch left nothing";

  // Still full: more failures are counted, the stretch keeps its start.
  env.advance(std::chrono::seconds(5));
  wall += 5'000'000;
  Batch again;
  again.faults.push_back({fault_at(k, k), Bytes(200, 7)});
  EXPECT_FALSE(store.write(again).ok());
  EXPECT_EQ(store.health().failed_writes, 2u);
  EXPECT_EQ(store.health().failing_since_us, wall - 5'000'000);

  // Space returns: the uplink acknowledges the queued faults (ack never throws).
  std::vector<std::uint64_t> seqs;
  for (const auto& e : store.peek_outbox(100'000, 1u << 30)) seqs.push_back(e.seq);
  EXPECT_EQ(store.ack(seqs).value_or(0), seqs.size());
  Batch small;
  small.faults.push_back({fault_at(k, k), Bytes(10, 7)});
  const auto r = store.write(small);
  ASSERT_TRUE(r.ok()) << r.status().message;
  EXPECT_FALSE(store.health().failing);
  EXPECT_EQ(store.health().failing_since_us, 0);
}

TEST(DiskBudget, BudgetLargerThanTheFileSystemIsClampedWithAWarning) {
  TempDir dir;
  std::ostringstream logged;
  auto logger = std::make_shared<spdlog::logger>(
      "clamp", std::make_shared<spdlog::sinks::ostream_sink_mt>(logged));
  constexpr std::uint64_t kHuge = 1ull << 60;  // 1 EiB: no test machine has that
  Store store(StoreOptions{.path = dir.file("clamp.db"), .max_bytes = kHuge, .logger = logger});
  const auto h = store.health();
  EXPECT_EQ(h.configured_budget_bytes, kHuge);
  EXPECT_LT(h.effective_budget_bytes, kHuge);
  EXPECT_GT(h.effective_budget_bytes, 0u);
  EXPECT_EQ(store.effective_budget(), h.effective_budget_bytes);
  EXPECT_EQ(store.stats().budget_bytes, h.effective_budget_bytes);
  EXPECT_NE(logged.str().find("clamped"), std::string::npos) << logged.str();
  EXPECT_NE(logged.str().find("storage.max_mb"), std::string::npos) << logged.str();

  // A budget the disk can hold is left alone, silently.
  std::ostringstream quiet;
  auto quiet_logger = std::make_shared<spdlog::logger>(
      "noclamp", std::make_shared<spdlog::sinks::ostream_sink_mt>(quiet));
  Store small(
      StoreOptions{.path = dir.file("small.db"), .max_bytes = 1 << 20, .logger = quiet_logger});
  EXPECT_EQ(small.health().effective_budget_bytes, 1u << 20);
  EXPECT_EQ(quiet.str().find("clamped"), std::string::npos);
}

// Errors that alternate (a full disk fails writes and acks in turn) are limited per message:
// each distinct message once per window, then one line with its count.
TEST(RateLimitedLog, AlternatingMessagesAreEachLimitedWithACount) {
  std::ostringstream out;
  auto logger = std::make_shared<spdlog::logger>(
      "rl-test", std::make_shared<spdlog::sinks::ostream_sink_st>(out));
  logger->set_pattern("%v");
  ManualEnv env;  // the windows run on its steady clock: 100 reports take no real time
  RateLimitedLog log(logger, std::chrono::seconds(10), env);
  int written = 0;
  for (int i = 0; i < 100; ++i) {
    written += log.report("write failed") ? 1 : 0;
    written += log.report("ack failed") ? 1 : 0;
    env.advance(std::chrono::milliseconds(20));  // 4 s in all: inside one window
  }
  EXPECT_EQ(written, 2) << out.str();
  EXPECT_EQ(log.suppressed(), 198u);
  env.advance(std::chrono::seconds(10));
  EXPECT_TRUE(log.report("write failed"));
  EXPECT_NE(out.str().find("write failed (repeated 100 times in the last"), std::string::npos)
      << out.str();
  log.resolved("works again");
  EXPECT_NE(out.str().find("works again (after 'ack failed', repeated 99 more times)"),
            std::string::npos)
      << out.str();
  EXPECT_EQ(log.suppressed(), 0u);
  // A failure right after the recovery (a disk flipping between full and working) is counted:
  // the window of its message runs on.
  env.advance(std::chrono::seconds(1));
  EXPECT_FALSE(log.report("write failed"));
  EXPECT_EQ(log.suppressed(), 1u);
  std::size_t lines = 0;
  for (const char c : out.str()) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, 4u) << out.str();
}

}  // namespace
}  // namespace fleetgw::storage
