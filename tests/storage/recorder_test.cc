// Recorder (contract C): group commit by WALL-clock time, never by bus time; urgent records go at
// once; health() reports the store's view.
#include <gtest/gtest.h>

#include <chrono>

#include "gateway/config/config.h"
#include "gateway/runtime/recorder.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "storage_test_util.h"

namespace fleetgw::runtime {
namespace {

using storage::testing::TempDir;
using Clock = std::chrono::steady_clock;

motinova::DecodedMessage bms_status(double voltage, double soc) {
  const motinova::MessageDesc* d = motinova::Catalogue::standard().find(0x720, 0x10);
  EXPECT_NE(d, nullptr);
  const auto frame = motinova::MessageWriter(*d, motinova::DecodeOptions{})
                         .value("voltage_v", voltage)
                         .value("soc_pct", soc)
                         .frame();
  static const motinova::DecodeOptions options{};  // the message points into it
  motinova::DecodedMessage msg;
  motinova::decode(frame, motinova::Catalogue::standard(), options, msg);
  return msg;
}

TEST(Recorder, CommitsByWallClockNotByBusTime) {
  TempDir dir;
  storage::Store store(storage::StoreOptions{.path = dir.file("rec.db")});
  config::Config config;
  config.storage.flush_ms = 200;
  ManualEnv env;  // frozen: a replay far faster than real time
  const auto t0 = Micros(1'700'000'000'000'000);
  Recorder recorder(config, store, t0, env);

  // One bus-hour of parked-bike traffic (a BMS status every second) in "no" wall time.
  for (int s = 0; s < 3600; ++s) {
    const Micros now = t0 + Micros(std::int64_t{s} * 1'000'000);
    recorder.on_message(bms_status(40.0 + (s % 7) * 0.1, 80), now);
    recorder.tick(now);
  }
  // The old recorder flushed every 200 ms of bus time: 18,000 transactions. Now only urgent
  // records (pack snapshots) commit before the wall-clock deadline.
  const auto during = recorder.batches_written();
  EXPECT_LT(during, 100u) << "commits follow the wall clock, not bus time";
  ASSERT_GT(recorder.pending_records(), 0u) << "telemetry waits for its deadline";
  EXPECT_FALSE(recorder.urgent());
  const auto deadline = recorder.flush_deadline();
  ASSERT_TRUE(deadline.has_value());
  EXPECT_LE(*deadline, env.steady_now() + std::chrono::milliseconds(200));

  // 200 ms of wall time later the next tick writes everything in one transaction.
  env.advance(std::chrono::milliseconds(200));
  recorder.tick(t0 + Micros(3600'000'000));
  EXPECT_EQ(recorder.batches_written(), during + 1);
  EXPECT_EQ(recorder.pending_records(), 0u);
  EXPECT_FALSE(recorder.flush_deadline().has_value()) << "nothing pending, no deadline";
  std::uint64_t telemetry = 0;
  for (const auto& [table, rows] : store.stats().table_rows) {
    if (table == "telemetry") telemetry = rows;
  }
  EXPECT_GT(telemetry, 30u) << "one sample per parked minute reached the store";

  const auto h = recorder.health();
  EXPECT_FALSE(h.failing);
  EXPECT_EQ(h.dropped_records, 0u);
  EXPECT_EQ(h.pending_records, 0u);
}

motinova::DecodedMessage mc_fault_word(std::uint32_t word) {
  const motinova::MessageDesc* d = motinova::Catalogue::standard().find(0x710, 0x11);
  EXPECT_NE(d, nullptr);
  const auto frame =
      motinova::MessageWriter(*d, motinova::DecodeOptions{}).raw("raw", word).frame();
  static const motinova::DecodeOptions options{};  // the message points into it
  motinova::DecodedMessage msg;
  motinova::decode(frame, motinova::Catalogue::standard(), options, msg);
  return msg;
}

TEST(Recorder, FullDiskBoundsRetryMemoryDropsTelemetryAndReports) {
  TempDir dir;
  const std::string path = dir.file("full.db");
  std::uint64_t pages = 0;
  {
    storage::Store fresh(storage::StoreOptions{.path = path});
    pages = fresh.stats().page_count;
  }
  // A "disk" with 4 pages to spare beyond the empty schema; fault events (never evicted) fill it.
  ManualEnv env;  // one Env for the store and the recorder, as `fleetgw run` has
  storage::Store store(
      storage::StoreOptions{.path = path, .max_page_count = pages + 4, .env = &env});
  config::Config config;
  const auto t0 = Micros(1'700'000'000'000'000);
  Recorder recorder(config, store, t0, env);
  recorder.set_retry_memory_bytes(16 * 1024);
  for (int s = 0; s < 4 * 3600; ++s) {  // 4 bus-hours at 10x: 1440 s of wall time
    const Micros now = t0 + Micros(std::int64_t{s} * 1'000'000);
    env.advance(std::chrono::milliseconds(100));
    recorder.on_message(bms_status(40.0 + (s % 7) * 0.1, 80), now);
    // An MC fault raised and cleared every 20 s.
    recorder.on_message(mc_fault_word((s / 10) % 2 == 0 ? 0x1u : 0x0u), now);
    recorder.tick(now);  // never throws, whatever the store says
  }
  const auto h = recorder.health();
  EXPECT_TRUE(h.failing);
  EXPECT_EQ(h.last_error, "disk full (SQLITE_FULL)");
  EXPECT_GT(h.failed_writes, 100u);
  // Stamped on the Env's wall clock (a real clock read would be years after it).
  EXPECT_GT(h.failing_since_us, ManualEnv().wall_now().count());
  EXPECT_LE(h.failing_since_us, env.wall_now().count());
  EXPECT_GT(h.dropped_records, 0u) << "retry memory is bounded: the oldest telemetry went";
  EXPECT_LT(h.pending_records, 2000u) << "what is held stays near the bound";
  // Retries follow the wall clock (once a second), not every tick (14,400 ticks).
  EXPECT_GT(recorder.write_failures(), 100u);
  EXPECT_LE(recorder.write_failures(), 1440u + 10u);
  // flush() hands the store's code to its caller: the engine's stage backs off on a kFull.
  ASSERT_GT(h.pending_records, 0u);
  const FlushOutcome out = recorder.flush(t0 + Micros(std::int64_t{4 * 3600} * 1'000'000));
  EXPECT_EQ(out.status.code, StatusCode::kFull) << out.status.message;
  EXPECT_NE(out.status.message.find("SQLITE_FULL"), std::string::npos) << out.status.message;
  EXPECT_GT(recorder.pending_records(), 0u) << "records kept for the retry";
}

TEST(Recorder, ARefusedBatchIsDroppedAndCountedNotRetried) {
  TempDir dir;
  ManualEnv env;
  storage::Store store(storage::StoreOptions{.path = dir.file("refused.db"), .env = &env});
  config::Config config;
  const auto t0 = Micros(1'700'000'000'000'000);
  Recorder recorder(config, store, t0, env);
  // Priority 99 is outside every kind's range: the store refuses the batch (kInvalid).
  recorder.queue_message(storage::UplinkMessage{storage::OutboxKind::kInfo, 99, {1, 2, 3}});
  const FlushOutcome out = recorder.flush(t0);
  EXPECT_TRUE(out.status.ok()) << "nothing is kept to retry: " << out.status.message;
  EXPECT_EQ(out.records, 0u);
  EXPECT_EQ(recorder.pending_records(), 0u);
  EXPECT_EQ(recorder.health().dropped_records, 1u);
  EXPECT_NE(recorder.health().last_error.find("priority"), std::string::npos)
      << recorder.health().last_error;
  // The next good batch goes through: the refused one does not block the queue.
  recorder.queue_message(storage::UplinkMessage{
      storage::OutboxKind::kInfo, static_cast<int>(storage::OutboxPriority::kPack), {4}});
  EXPECT_TRUE(recorder.flush(t0).status.ok());
  EXPECT_EQ(recorder.batches_written(), 1u);
}

}  // namespace
}  // namespace fleetgw::runtime
