// Disk budget: past max_bytes the oldest telemetry goes first, then pack snapshots; faults,
// rides, lock events and command results are never evicted; every eviction is counted,
// persisted, reported through write() and queued as an eviction_report outbox entry.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

void write_precious(Store& store) {
  Batch b;
  b.now_us = 1;
  for (int i = 0; i < 50; ++i) b.faults.push_back({fault_at(i, i), payload_of("fault")});
  for (int i = 0; i < 10; ++i) {
    b.rides.push_back({ride_named("r" + std::to_string(i), i, true), payload_of("ride")});
  }
  for (int i = 0; i < 20; ++i) b.locks.push_back({lock_at(i), payload_of("lock")});
  for (int i = 0; i < 10; ++i) {
    b.command_results.push_back({command_result("c" + std::to_string(i), i), payload_of("cmd")});
  }
  store.write(b);
}

TEST(Budget, TelemetryEvictedFirstPreciousRecordsKept) {
  TempDir dir;
  const std::string path = dir.file("budget.db");
  constexpr std::uint64_t kBudget = 2 << 20;
  std::uint64_t reported_telemetry = 0, reported_outbox = 0, passes = 0;
  std::int64_t t = 1'000;
  {
    Store store(StoreOptions{.path = path, .max_bytes = kBudget});
    write_precious(store);
    Batch packs;
    for (int i = 0; i < 100; ++i) packs.packs.push_back({pack_at(i), payload_of("pack")});
    store.write(packs);

    // ~3x the budget in telemetry with 64-byte uplink payloads.
    for (int batch = 0; batch < 120; ++batch) {
      Batch b;
      b.now_us = t;
      for (int i = 0; i < 500; ++i, t += 1000) {
        b.telemetry.push_back({telemetry_at(t), Bytes(64, static_cast<std::uint8_t>(i))});
      }
      auto r = store.write(b);
      ASSERT_LE(store.live_bytes(), kBudget) << "batch " << batch;
      if (r.ok() && r->eviction) {
        ++passes;
        EXPECT_EQ(r->eviction->pack_snapshot_rows, 0u) << "telemetry was still available";
        EXPECT_FALSE(r->eviction->budget_exhausted);
        // Eviction starts below the budget: the WAL allowance and the reserve are inside it.
        EXPECT_LT(r->eviction->budget_bytes, kBudget);
        EXPECT_GT(r->eviction->bytes_before, r->eviction->budget_bytes);
        EXPECT_LE(r->eviction->bytes_after,
                  static_cast<std::uint64_t>(r->eviction->budget_bytes * 0.9));
        EXPECT_GT(r->eviction->telemetry_rows, 0u);
        reported_telemetry += r->eviction->telemetry_rows;
        reported_outbox += r->eviction->outbox_rows;
        ASSERT_TRUE(r->eviction->oldest_telemetry_kept_us.has_value());
      }
    }
    ASSERT_GT(passes, 1u);
    EXPECT_EQ(reported_outbox, reported_telemetry) << "unsent telemetry leaves with its sample";

    auto c = counts(store);
    EXPECT_EQ(c["fault_events"], 50u);
    EXPECT_EQ(c["rides"], 10u);
    EXPECT_EQ(c["lock_events"], 20u);
    EXPECT_EQ(c["command_results"], 10u);
    EXPECT_EQ(c["pack_snapshots"], 100u);
    EXPECT_EQ(c["telemetry"] + reported_telemetry, 60'000u);

    // The survivors are the newest samples, and no outbox entry points at an evicted sample.
    Database raw(path);
    EXPECT_EQ(raw.query_int64("SELECT min(id) FROM telemetry"),
              static_cast<std::int64_t>(reported_telemetry) + 1);
    EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox WHERE kind = 'telemetry' AND "
                              "source_id NOT IN (SELECT id FROM telemetry)"),
              0);
    EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox WHERE kind = 'eviction_report'"),
              static_cast<std::int64_t>(passes));
  }
  // Counters persist; the file really shrank (incremental vacuum + checkpoint at close).
  Store store(StoreOptions{.path = path, .max_bytes = kBudget});
  auto stats = store.stats();
  std::map<std::string, EvictionCounter> ev;
  for (const auto& e : stats.evictions) ev[e.table] = e;
  EXPECT_EQ(ev["telemetry"].rows, reported_telemetry);
  EXPECT_EQ(ev["telemetry"].passes, passes);
  EXPECT_EQ(ev["pack_snapshots"].rows, 0u);
  EXPECT_EQ(ev["outbox"].rows, reported_outbox);
  EXPECT_LE(stats.file_bytes, kBudget);
  EXPECT_GT(stats.file_bytes, kBudget / 2);

  // The report is queued at priority 1 with a JSON payload the gateway can forward or convert.
  bool found = false;
  for (const auto& e : store.peek_outbox(100'000, 1 << 30)) {
    if (e.kind != OutboxKind::kEvictionReport) continue;
    EXPECT_EQ(e.priority, 1);
    auto j = nlohmann::json::parse(std::string(e.payload.begin(), e.payload.end()));
    EXPECT_GT(j["evicted"]["telemetry"].get<std::uint64_t>(), 0u);
    // The limit telemetry is evicted at: the budget minus the WAL allowance and the reserve.
    EXPECT_LE(j["budget_bytes"].get<std::uint64_t>(),
              kBudget - stats.wal_allowance_bytes - stats.reserve_bytes);
    found = true;
  }
  EXPECT_TRUE(found);
}

TEST(Budget, PackSnapshotsEvictedWhenNoTelemetryLeft) {
  TempDir dir;
  constexpr std::uint64_t kBudget = 1 << 20;
  Store store(StoreOptions{.path = dir.file("packs.db"), .max_bytes = kBudget});
  write_precious(store);
  std::uint64_t evicted_packs = 0;
  for (int batch = 0; batch < 40; ++batch) {
    Batch b;
    b.now_us = batch;
    for (int i = 0; i < 200; ++i) b.packs.push_back({pack_at(batch * 1000 + i), Bytes(80, 1)});
    auto r = store.write(b);
    if (r.ok() && r->eviction) {
      EXPECT_EQ(r->eviction->telemetry_rows, 0u);
      evicted_packs += r->eviction->pack_snapshot_rows;
    }
    ASSERT_LE(store.live_bytes(), kBudget);
  }
  EXPECT_GT(evicted_packs, 0u);
  auto c = counts(store);
  EXPECT_EQ(c["pack_snapshots"] + evicted_packs, 8000u);
  EXPECT_EQ(c["fault_events"], 50u);
  EXPECT_EQ(c["rides"], 10u);
  EXPECT_EQ(c["lock_events"], 20u);
  EXPECT_EQ(c["command_results"], 10u);
}

TEST(Budget, TelemetryGoesBeforeAnyPackSnapshot) {
  TempDir dir;
  constexpr std::uint64_t kBudget = 1 << 20;
  Store store(StoreOptions{.path = dir.file("order.db"), .max_bytes = kBudget});
  // Old pack snapshots first, then newer telemetry: age alone would pick the packs.
  Batch packs;
  for (int i = 0; i < 1000; ++i) packs.packs.push_back({pack_at(i), Bytes(80, 1)});
  store.write(packs);
  std::uint64_t evicted_telemetry = 0;
  for (int batch = 0; batch < 40; ++batch) {
    Batch b;
    for (int i = 0; i < 500; ++i) {
      b.telemetry.push_back({telemetry_at(1'000'000 + batch * 500 + i), Bytes(64, 2)});
    }
    auto r = store.write(b);
    if (r.ok() && r->eviction) {
      evicted_telemetry += r->eviction->telemetry_rows;
      EXPECT_EQ(r->eviction->pack_snapshot_rows, 0u) << "batch " << batch;
    }
  }
  EXPECT_GT(evicted_telemetry, 0u);
  EXPECT_EQ(counts(store)["pack_snapshots"], 1000u);
}

TEST(Budget, NothingEvictableKeepsEverythingAndReportsOnce) {
  TempDir dir;
  constexpr std::uint64_t kBudget = 256 << 10;
  Store store(StoreOptions{.path = dir.file("full.db"), .max_bytes = kBudget});
  int exhausted_reports = 0;
  for (int batch = 0; batch < 20; ++batch) {
    Batch b;
    b.now_us = batch;
    for (int i = 0; i < 200; ++i) b.faults.push_back({fault_at(batch, i), Bytes(100, 3)});
    auto r = store.write(b);
    if (r.ok() && r->eviction) {
      EXPECT_TRUE(r->eviction->budget_exhausted);
      EXPECT_EQ(r->eviction->telemetry_rows + r->eviction->pack_snapshot_rows, 0u);
      ++exhausted_reports;
    }
  }
  EXPECT_GT(store.live_bytes(), kBudget);
  EXPECT_EQ(exhausted_reports, 1) << "reported on the transition, not on every batch";
  EXPECT_EQ(counts(store)["fault_events"], 4000u) << "faults are never dropped";
}

// Eviction finds the evicted samples' queued entries without an index on source_id (schema v7):
// through the telemetry priority, in queue order. Around them: samples already acknowledged,
// samples stored without an uplink payload, and other messages queued at the same priority,
// which must all stay as they are.
TEST(Budget, EvictionDeletesExactlyTheEvictedSamplesEntriesFromAMixedQueue) {
  TempDir dir;
  const std::string path = dir.file("mixed.db");
  constexpr std::uint64_t kBudget = 2 << 20;
  Store store(StoreOptions{.path = path, .max_bytes = kBudget});
  std::int64_t t = 1'000;
  std::uint64_t evicted_samples = 0, evicted_entries = 0, passes = 0;
  std::int64_t info_messages = 0;
  std::vector<std::int64_t> acked_samples;
  for (int batch = 0; batch < 120 && passes < 3; ++batch) {
    Batch b;
    b.now_us = t;
    for (int i = 0; i < 500; ++i, t += 1000) {
      // Every seventh sample is stored without an uplink payload (nothing queued for it).
      std::optional<Bytes> uplink;
      if (i % 7 != 0) uplink = Bytes(64, static_cast<std::uint8_t>(i));
      b.telemetry.push_back({telemetry_at(t), std::move(uplink)});
    }
    // A message of another kind at the telemetry's priority, between the samples' entries.
    b.messages.push_back({OutboxKind::kInfo, kLowestPriority, Bytes(16, 7)});
    const auto r = store.write(b);
    ASSERT_TRUE(r.ok()) << r.status().message;
    ++info_messages;
    if (r->eviction && r->eviction->telemetry_rows > 0) {
      ++passes;
      evicted_samples += r->eviction->telemetry_rows;
      evicted_entries += r->eviction->outbox_rows;
    }
    if (batch == 3) {
      // Acknowledge every third queued sample of the oldest batches: no longer queued.
      std::vector<std::uint64_t> acked;
      for (const auto& e : store.peek_outbox(1500, 1 << 30)) {
        if (e.kind != OutboxKind::kTelemetry || e.seq % 3 != 0) continue;
        acked.push_back(e.seq);
        acked_samples.push_back(*e.source_id);
      }
      store.release_all();
      ASSERT_EQ(store.ack(acked).value_or(0), acked.size());
    }
  }
  ASSERT_EQ(passes, 3u) << "the budget was not reached three times";
  Database raw(path);
  // Nothing queued for a sample that is gone, ...
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox WHERE kind = 'telemetry' AND "
                            "source_id NOT IN (SELECT id FROM telemetry)"),
            0);
  // ... every kept sample that had a payload and was not acknowledged is still queued ...
  const std::int64_t oldest_kept = raw.query_int64("SELECT min(id) FROM telemetry").value_or(0);
  const auto acked_kept = std::count_if(acked_samples.begin(), acked_samples.end(),
                                        [&](std::int64_t id) { return id >= oldest_kept; });
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox WHERE kind = 'telemetry'"),
            *raw.query_int64("SELECT count(*) FROM telemetry WHERE (id - 1) % 500 % 7 != 0") -
                acked_kept);
  // ... the eviction reports counted exactly the entries that went: those of the evicted
  // samples that had a payload and were not acknowledged ...
  EXPECT_EQ(evicted_samples, static_cast<std::uint64_t>(oldest_kept - 1));
  std::uint64_t expected_entries = 0;
  for (std::int64_t id = 1; id < oldest_kept; ++id) {
    if ((id - 1) % 500 % 7 != 0) ++expected_entries;
  }
  expected_entries -= static_cast<std::uint64_t>(acked_samples.size() - acked_kept);
  EXPECT_EQ(evicted_entries, expected_entries);
  // ... and no other message at that priority went with them.
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox WHERE kind = 'info'"), info_messages);
}

}  // namespace
}  // namespace fleetgw::storage
