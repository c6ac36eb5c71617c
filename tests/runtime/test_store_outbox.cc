// StoreOutbox (gateway/runtime/store_outbox.h): the SQLite outbox as the uplink reads it.
//  * An eviction report is stored as the fleetgw.v1.EvictionReport it is published as, made once
//    in the eviction pass, and passed on as stored, with the content the JSON conversion of
//    earlier versions gave.
//  * A JSON report left by an earlier version still leaves as that EvictionReport.
//  * A kind this version does not know reaches the uplink under its stored name (it refuses it).
//  * Acknowledged rows a failing disk could not delete are not offered again, and their deletion
//    is retried on the engine's one back-off, timed by the injected Env: not before 1 s, then
//    2 s, acks arriving meanwhile waiting with them instead of asking the failing disk again.
#include <gtest/gtest.h>

#include <optional>

#include "env/env.h"
#include "fleetgw/v1/eviction.pb.h"
#include "gateway/domain/payloads.h"
#include "gateway/runtime/store_outbox.h"
#include "storage/sqlite.h"
#include "tests/storage/storage_test_util.h"

namespace fleetgw::runtime {
namespace {

using namespace storage;
using namespace storage::testing;

// Writes telemetry until a pass evicts; returns that pass.
EvictionPass fill_until_eviction(Store& store) {
  std::int64_t t = 1'000;
  for (int batch = 0; batch < 200; ++batch) {
    Batch b;
    b.now_us = t;
    for (int i = 0; i < 500; ++i, t += 1000) {
      b.telemetry.push_back({telemetry_at(t), Bytes(64, static_cast<std::uint8_t>(i))});
    }
    const auto r = store.write(b);
    if (r.ok() && r->eviction) return *r->eviction;
  }
  ADD_FAILURE() << "no eviction";
  return {};
}

std::optional<uplink::OutgoingRecord> eviction_record(StoreOutbox& outbox) {
  for (auto& e : outbox.peek(100'000, std::size_t{1} << 30, {})) {
    if (e.kind == uplink::kind::kEviction) return e;
  }
  return std::nullopt;
}

void expect_same_report(const std::string& a, const std::string& b) {
  v1::EvictionReport x, y;
  ASSERT_TRUE(x.ParseFromString(a));
  ASSERT_TRUE(y.ParseFromString(b));
  EXPECT_EQ(x.evicted_records(), y.evicted_records());
  EXPECT_EQ(x.last_sequence(), y.last_sequence());
  EXPECT_EQ(x.newest_created_at_us(), y.newest_created_at_us());
  EXPECT_EQ(x.reason(), y.reason());
  EXPECT_EQ(x.evicted_by_kind().size(), y.evicted_by_kind().size());
  for (const auto& [k, v] : x.evicted_by_kind()) {
    ASSERT_TRUE(y.evicted_by_kind().contains(k)) << k;
    EXPECT_EQ(y.evicted_by_kind().at(k), v) << k;
  }
}

TEST(StoreOutbox, EvictionReportIsStoredAsItsProtobufAndPassedOnAsStored) {
  fleetgw::testing::TempDir dir;
  StoreOptions options{.path = dir.file("o.db"), .max_bytes = 2 << 20};
  options.encode_eviction_report = domain::eviction_report_payload;
  Store store(options);
  const EvictionPass pass = fill_until_eviction(store);
  StoreOutbox outbox(store);
  const auto record = eviction_record(outbox);
  ASSERT_TRUE(record.has_value());

  // The bytes in SQLite are the bytes the uplink gets: nothing is converted on the way out.
  bool compared = false;
  store.visit_outbox(OutboxKind::kEvictionReport, [&](const OutboxRow& row) {
    if (row.seq != record->seq) return;
    EXPECT_EQ(std::string(row.payload.begin(), row.payload.end()), record->payload);
    compared = true;
  });
  EXPECT_TRUE(compared);

  v1::EvictionReport report;
  ASSERT_TRUE(report.ParseFromString(record->payload));
  EXPECT_EQ(report.last_sequence(), record->seq);
  EXPECT_GT(report.evicted_by_kind().at("telemetry"), 0u);
  // What earlier versions sent for the same pass (JSON stored, converted at every peek).
  expect_same_report(record->payload, eviction_payload_from_json(pass.to_json(), record->seq));
}

TEST(StoreOutbox, AJsonEvictionReportOfAnEarlierVersionStillLeavesAsProtobuf) {
  fleetgw::testing::TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db"), .max_bytes = 2 << 20});  // no encoder
  const EvictionPass pass = fill_until_eviction(store);
  StoreOutbox outbox(store);
  const auto record = eviction_record(outbox);
  ASSERT_TRUE(record.has_value());
  v1::EvictionReport report;
  ASSERT_TRUE(report.ParseFromString(record->payload));
  EXPECT_EQ(report.last_sequence(), record->seq);
  const auto encoded = domain::eviction_report_payload(pass, record->seq);
  expect_same_report(record->payload, std::string(encoded.begin(), encoded.end()));
}

TEST(StoreOutbox, AnUnknownStoredKindReachesTheUplinkByItsStoredName) {
  fleetgw::testing::TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  Batch b;
  b.now_us = 5;
  b.faults.push_back({fault_at(1, 2), payload_of("fault")});
  b.locks.push_back({lock_at(3), payload_of("lock")});
  store.write(b);
  {
    Database raw(store.path());
    raw.exec("UPDATE outbox SET kind = 'teleport' WHERE kind = 'fault'");
  }
  StoreOutbox outbox(store);
  const auto records = outbox.peek(10, 1 << 20, {});
  ASSERT_EQ(records.size(), 2u);
  EXPECT_EQ(records[0].kind, "teleport");
  EXPECT_EQ(records[1].kind, uplink::kind::kLock);
}

TEST(StoreOutbox, ADeleteAFailingDiskRefusedIsRetriedOnTheEnginesBackOff) {
  using namespace std::chrono_literals;
  fleetgw::testing::TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  Batch b;
  b.now_us = 5;
  for (int i = 0; i < 4; ++i) b.faults.push_back({fault_at(i + 1, i), payload_of("fault")});
  ASSERT_TRUE(store.write(b).ok());
  ManualEnv env;
  StoreOutbox outbox(store, env);
  const auto records = outbox.peek(10, 1 << 20, {});
  ASSERT_EQ(records.size(), 4u);
  const std::uint64_t s0 = records[0].seq, s1 = records[1].seq, s2 = records[2].seq;
  Database raw(store.path());
  raw.exec("CREATE TRIGGER full BEFORE DELETE ON outbox BEGIN SELECT RAISE(ABORT, 'full'); END");
  const auto failures = [&] { return store.health().failed_writes; };
  const auto t0 = env.steady_now();

  const std::uint64_t first[] = {s0, s1};
  outbox.ack(first);
  EXPECT_EQ(failures(), 1u);
  EXPECT_EQ(outbox.undeleted(), 2u);
  EXPECT_EQ(outbox.next_retry(), t0 + 1s);
  EXPECT_EQ(outbox.peek(10, 1 << 20, {}).size(), 2u) << "the broker has them: not offered again";

  // An ack during the back-off waits with the others: the failing disk is not asked.
  const std::uint64_t second[] = {s2};
  outbox.ack(second);
  EXPECT_EQ(failures(), 1u);
  EXPECT_EQ(outbox.undeleted(), 3u);
  env.advance(999ms);
  outbox.retry_deletes();
  EXPECT_EQ(failures(), 1u) << "not before its time on the injected clock";

  // At its time it is retried; a second failure doubles the wait.
  env.advance(1ms);
  outbox.retry_deletes();
  EXPECT_EQ(failures(), 2u);
  EXPECT_EQ(outbox.next_retry(), t0 + 1s + 2s);

  raw.exec("DROP TRIGGER full");
  env.advance(1999ms);
  outbox.peek(10, 1 << 20, {});
  EXPECT_EQ(outbox.undeleted(), 3u);
  env.advance(1ms);
  ASSERT_EQ(outbox.peek(10, 1 << 20, {}).size(), 1u);
  EXPECT_EQ(outbox.undeleted(), 0u);
  EXPECT_EQ(outbox.next_retry(), std::nullopt);
  EXPECT_EQ(outbox.stats().depth, 1u) << "the three acknowledged rows are gone from SQLite";
}

}  // namespace
}  // namespace fleetgw::runtime
