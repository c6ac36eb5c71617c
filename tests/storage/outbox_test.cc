// The outbox: priority-then-sequence order, in-flight tracking, exact acks, sequence numbers
// that are unique and gap-free across reopen and never reused, atomic batches.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

std::vector<std::uint64_t> seqs_of(const std::vector<OutboxRow>& entries) {
  std::vector<std::uint64_t> out;
  for (const auto& e : entries) out.push_back(e.seq);
  return out;
}

// One record of every kind, in an order unrelated to priority.
Batch mixed_batch(std::int64_t t) {
  Batch b;
  b.now_us = t;
  b.telemetry.push_back({telemetry_at(t), payload_of("tel")});
  b.packs.push_back({pack_at(t), payload_of("pack")});
  b.locks.push_back({lock_at(t), payload_of("lock")});
  b.rides.push_back({ride_named("ride-" + std::to_string(t), t, true), payload_of("ride")});
  b.faults.push_back({fault_at(t, 7), payload_of("fault")});
  b.command_results.push_back({command_result("c-" + std::to_string(t), t), payload_of("cmd")});
  return b;
}

TEST(Outbox, PeekOrdersByPriorityThenSequence) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  store.write(mixed_batch(1000));
  store.write(mixed_batch(2000));
  auto entries = store.peek_outbox(100, 1 << 20);
  ASSERT_EQ(entries.size(), 12u);
  const std::vector<OutboxKind> expected_kinds = {
      OutboxKind::kCommandResult, OutboxKind::kCommandResult, OutboxKind::kFault,
      OutboxKind::kFault,         OutboxKind::kRide,          OutboxKind::kRide,
      OutboxKind::kLock,          OutboxKind::kLock,          OutboxKind::kPack,
      OutboxKind::kPack,          OutboxKind::kTelemetry,     OutboxKind::kTelemetry};
  for (std::size_t i = 0; i < entries.size(); ++i) {
    EXPECT_EQ(entries[i].kind, expected_kinds[i]) << "entry " << i;
    if (i > 0) {
      const auto& a = entries[i - 1];
      const auto& b = entries[i];
      EXPECT_TRUE(a.priority < b.priority || (a.priority == b.priority && a.seq < b.seq))
          << "entry " << i;
    }
  }
  EXPECT_EQ(entries[0].priority, 0);
  EXPECT_EQ(entries.back().priority, 5);
  EXPECT_EQ(entries[0].created_us, 1000);
  EXPECT_EQ(entries[0].payload, payload_of("cmd"));
  EXPECT_TRUE(entries[0].source_id.has_value());
}

// A kind this version does not know (a newer version wrote it) is never guessed as another kind:
// the entry comes back marked with its stored name, for the reader to refuse and drop.
TEST(Outbox, AnUnknownStoredKindIsRefusedNotGuessed) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  store.write(mixed_batch(1000));
  {
    Database raw(store.path());
    raw.exec("UPDATE outbox SET kind = 'teleport' WHERE kind = 'fault'");
  }
  const auto entries = store.peek_outbox(100, 1 << 20);
  ASSERT_EQ(entries.size(), 6u);
  int unknown = 0;
  for (const auto& e : entries) {
    if (!e.unknown_kind) continue;
    ++unknown;
    EXPECT_EQ(*e.unknown_kind, "teleport");
    EXPECT_EQ(e.payload, payload_of("fault"));
  }
  EXPECT_EQ(unknown, 1);
}

TEST(Outbox, PeekSkipsInFlightAndHonoursLimits) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  Batch b;
  b.now_us = 1;
  for (int i = 0; i < 10; ++i) b.telemetry.push_back({telemetry_at(i), Bytes(100, 0xab)});
  store.write(b);

  auto first = store.peek_outbox(3, 1 << 20);
  EXPECT_EQ(seqs_of(first), (std::vector<std::uint64_t>{1, 2, 3}));
  EXPECT_EQ(store.in_flight(), 3u);
  auto second = store.peek_outbox(3, 250);  // byte cap: two 100-byte payloads fit, not three
  EXPECT_EQ(seqs_of(second), (std::vector<std::uint64_t>{4, 5}));
  auto tiny = store.peek_outbox(3, 10);  // never starve: the first entry always comes
  EXPECT_EQ(seqs_of(tiny), (std::vector<std::uint64_t>{6}));

  const std::vector<std::uint64_t> back = {2};
  store.release(back);  // publish of #2 failed: it is due again, ahead of newer entries
  EXPECT_EQ(seqs_of(store.peek_outbox(2, 1 << 20)), (std::vector<std::uint64_t>{2, 7}));
  store.release_all();
  EXPECT_EQ(store.in_flight(), 0u);
  EXPECT_EQ(store.peek_outbox(100, 1 << 20).size(), 10u);
  EXPECT_TRUE(store.peek_outbox(0, 1 << 20).empty());
}

TEST(Outbox, AckDeletesOnlyAcknowledged) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  store.write(mixed_batch(1000));
  auto all = store.peek_outbox(100, 1 << 20);
  ASSERT_EQ(all.size(), 6u);
  const std::vector<std::uint64_t> acked = {all[1].seq, all[4].seq, 9999};  // 9999: unknown
  EXPECT_EQ(store.ack(acked).value_or(0), 2u);
  store.release_all();
  auto left = seqs_of(store.peek_outbox(100, 1 << 20));
  std::vector<std::uint64_t> expected = {all[0].seq, all[2].seq, all[3].seq, all[5].seq};
  EXPECT_EQ(left, expected);
  // The records themselves stay: acking only removes the queue entry.
  EXPECT_EQ(store.stats().table_rows.size(), Store::exportable_tables().size());
  std::uint64_t faults = 0;
  store.export_table("fault_events", 0, [&](const nlohmann::json&) { ++faults; });
  EXPECT_EQ(faults, 1u);
  EXPECT_EQ(store.ack(std::vector<std::uint64_t>{all[1].seq}).value_or(9), 0u)
      << "double ack is harmless";
}

TEST(Outbox, AFailedAckReturnsItsStatusAndDeletesNothing) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("ackfail.db")});
  store.write(mixed_batch(1000));
  const auto all = seqs_of(store.peek_outbox(100, 1 << 20));
  ASSERT_EQ(all.size(), 6u);
  {
    Database raw(store.path());
    raw.exec("CREATE TRIGGER boom BEFORE DELETE ON outbox BEGIN SELECT RAISE(ABORT, 'boom'); END");
  }
  const auto failed = store.ack(all);  // never throws: the error is returned
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.status().message.find("boom"), std::string::npos) << failed.status().message;
  EXPECT_TRUE(store.health().failing);
  store.release_all();
  EXPECT_EQ(store.peek_outbox(100, 1 << 20).size(), 6u) << "nothing deleted: sent again later";
  {
    Database raw(store.path());
    raw.exec("DROP TRIGGER boom");
  }
  const auto acked = store.ack(all);
  ASSERT_TRUE(acked.ok()) << acked.status().message;
  EXPECT_EQ(*acked, 6u);
  EXPECT_FALSE(store.health().failing);
}

TEST(Outbox, SequenceNumbersGapFreeAcrossReopenAndNeverReused) {
  TempDir dir;
  const std::string path = dir.file("seq.db");
  std::vector<std::uint64_t> seen;
  for (int round = 0; round < 4; ++round) {
    Store store(StoreOptions{.path = path});
    for (int i = 0; i < 5; ++i) {
      auto r = store.write(mixed_batch(round * 100 + i));
      ASSERT_TRUE(r.ok()) << r.status().message;
      ASSERT_EQ(r->end_seq - r->first_seq, 6u);
      for (auto s = r->first_seq; s < r->end_seq; ++s) seen.push_back(s);
    }
    // Ack everything: an empty outbox must not let the counter restart.
    auto entries = store.peek_outbox(1000, 1 << 30);
    store.ack(seqs_of(entries));
    EXPECT_TRUE(store.peek_outbox(1000, 1 << 30).empty());
  }
  std::vector<std::uint64_t> expected(seen.size());
  std::iota(expected.begin(), expected.end(), 1);
  EXPECT_EQ(seen, expected);
}

TEST(Outbox, RejectedBatchStoresNothingAndBurnsNoNumbers) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  store.write(mixed_batch(1));
  const auto next = store.next_seq();

  Batch bad = mixed_batch(2);
  bad.rides.push_back({ride_named("", 2, false), std::nullopt});
  const auto rejected = store.write(bad);
  ASSERT_FALSE(rejected.ok()) << "empty ride id must be rejected";
  EXPECT_EQ(rejected.status().code, StatusCode::kInvalid);
  EXPECT_EQ(rejected.status().message, "storage: Batch.rides[1].ride_id: empty");
  EXPECT_EQ(store.next_seq(), next);
  EXPECT_EQ(store.outbox_depth().size(), 6u);

  // A failure inside the transaction (here: a CHECK constraint) rolls everything back too.
  Batch failing = mixed_batch(3);
  failing.meta.emplace_back("k", "v");
  {
    Database raw(store.path());
    raw.exec("CREATE TRIGGER boom BEFORE INSERT ON meta BEGIN SELECT RAISE(ABORT, 'boom'); END");
  }
  const auto failed = store.write(failing);  // never throws: the error is returned
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.status().message.find("boom"), std::string::npos) << failed.status().message;
  EXPECT_TRUE(store.health().failing);
  EXPECT_EQ(store.health().failed_writes, 2u) << "the rejected batch and the failed one";
  EXPECT_EQ(store.next_seq(), next);
  std::uint64_t total = 0;
  for (const auto& d : store.outbox_depth()) total += d.entries;
  EXPECT_EQ(total, 6u);
  {
    Database raw(store.path());
    raw.exec("DROP TRIGGER boom");
  }
  auto r = store.write(mixed_batch(4));
  ASSERT_TRUE(r.ok()) << r.status().message;
  EXPECT_EQ(r->first_seq, next) << "numbers of the rolled-back batch are handed out again";
  EXPECT_FALSE(store.health().failing) << "a successful write ends the failing stretch";
  EXPECT_EQ(store.health().failing_since_us, 0);
}

TEST(Outbox, ValidationNamesEntryAndField) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  auto expect_reject = [&](const Batch& b, const std::string& message) {
    const auto r = store.write(b);
    ASSERT_FALSE(r.ok()) << "expected rejection: " << message;
    EXPECT_EQ(r.status().code, StatusCode::kInvalid);
    EXPECT_EQ(r.status().message, message);
  };
  Batch b;
  b.telemetry.push_back({telemetry_at(-5), std::nullopt});
  expect_reject(b, "storage: Batch.telemetry[0].ts_us: negative timestamp -5");
  b = {};
  b.messages.push_back({OutboxKind::kStatus, 9, payload_of("x")});
  expect_reject(b, "storage: Batch.messages[0].priority: 9 outside 0..5");
  b = {};
  b.telemetry.push_back({telemetry_at(1), Bytes(Store::kMaxPayloadBytes + 1)});
  expect_reject(b, "storage: Batch.telemetry[0].uplink: payload of 1048577 bytes exceeds 1048576");
  b = {};
  b.meta.emplace_back("storage.next_seq", "1");
  expect_reject(b, "storage: Batch.meta[0].key: 'storage.next_seq' is reserved");
  b = {};
  auto p = pack_at(1);
  p.lifetime_json = "{oops";
  b.packs.push_back({p, std::nullopt});
  expect_reject(b, "storage: Batch.packs[0].lifetime_json: not valid JSON");
  b = {};
  auto f = fault_at(10, 1);
  f.last_seen_us = 5;
  b.faults.push_back({f, std::nullopt});
  expect_reject(b, "storage: Batch.faults[0].last_seen_us: before first_seen_us");
}

TEST(Outbox, DepthAndOldestUnsent) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  EXPECT_EQ(store.oldest_unsent_us(), std::nullopt);
  store.write(mixed_batch(500));
  store.write(mixed_batch(900));
  auto depth = store.outbox_depth();
  ASSERT_EQ(depth.size(), 6u);
  for (int p = 0; p < 6; ++p) {
    EXPECT_EQ(depth[p].priority, p);
    EXPECT_EQ(depth[p].entries, 2u);
  }
  EXPECT_EQ(depth[5].payload_bytes, 6u);  // "tel" twice
  EXPECT_EQ(store.oldest_unsent_us(), 500);
  std::vector<std::uint64_t> first_batch_seqs;
  for (std::uint64_t s = 1; s <= 6; ++s) first_batch_seqs.push_back(s);
  store.ack(first_batch_seqs);
  EXPECT_EQ(store.oldest_unsent_us(), 900);
}

TEST(Store, OpenRideSurvivesRestartAndIsUpdatedInPlace) {
  TempDir dir;
  const std::string path = dir.file("r.db");
  {
    Store store(StoreOptions{.path = path});
    Batch b;
    RideRow r = ride_named("ride-1", 100, false);
    r.distance_km = 1.0;
    b.rides.push_back({r, std::nullopt});  // checkpoint only: no uplink yet
    auto res = store.write(b);
    ASSERT_TRUE(res.ok()) << res.status().message;
    EXPECT_EQ(res->first_seq, res->end_seq) << "no outbox entry for a checkpoint";
  }
  Store store(StoreOptions{.path = path});
  auto open = store.open_rides();
  ASSERT_EQ(open.size(), 1u);
  EXPECT_EQ(open[0].ride_id, "ride-1");
  EXPECT_DOUBLE_EQ(open[0].distance_km, 1.0);
  EXPECT_EQ(open[0].assist_time_s, (std::map<std::string, double>{{"eco", 200}, {"tour", 340}}));

  RideRow closed = ride_named("ride-1", 100, true);
  closed.distance_km = 2.75;
  Batch b;
  b.rides.push_back({closed, payload_of("ride-final")});
  store.write(b);
  EXPECT_TRUE(store.open_rides().empty());
  auto stored = store.ride("ride-1");
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(stored->state, RideState::kClosed);
  closed.id = stored->id;
  EXPECT_EQ(*stored, closed);
  auto entries = store.peek_outbox(10, 1 << 20);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].source_id, stored->id);
}

TEST(Store, CommandJournalAndSeenIds) {
  TempDir dir;
  const std::string path = dir.file("c.db");
  {
    Store store(StoreOptions{.path = path});
    Batch b;
    b.commands.push_back({"cmd-1", 1'000, "received", 61'000});
    b.commands.push_back({"cmd-2", 2'000, "received", 5'000});
    store.write(b);
  }
  Store store(StoreOptions{.path = path});
  EXPECT_TRUE(store.command_seen("cmd-1", 3'000));
  EXPECT_TRUE(store.command_seen("cmd-2", 3'000));
  EXPECT_FALSE(store.command_seen("cmd-2", 5'000)) << "expired";
  EXPECT_FALSE(store.command_seen("cmd-3", 3'000));
  Batch b;
  b.commands.push_back({"cmd-1", 1'000, "done", 61'000});
  store.write(b);
  EXPECT_EQ(store.command("cmd-1")->state, "done");
  EXPECT_EQ(store.purge_expired_commands(10'000), 1u);
  EXPECT_FALSE(store.command("cmd-2").has_value());
  EXPECT_TRUE(store.command_seen("cmd-1", 10'000));
}

TEST(Store, MetaRoundTrip) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("m.db")});
  EXPECT_EQ(store.meta("vin"), std::nullopt);
  Batch b;
  b.meta.emplace_back("vin", "BIKE-0042");
  store.write(b);
  EXPECT_EQ(store.meta("vin"), "BIKE-0042");
}

TEST(Store, SecondWriterOnSameFileIsRefused) {
  TempDir dir;
  const std::string path = dir.file("w.db");
  Store first(StoreOptions{.path = path});
  try {
    Store second(StoreOptions{.path = path});
    FAIL() << "two writers on one database";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ".lock"), std::string::npos) << e.what();
  }
}

TEST(Store, FullDurabilityIsApplied) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("d.db"), .durability = Durability::kFull});
  store.write(mixed_batch(1));
  EXPECT_EQ(store.synchronous_mode(), 2);  // FULL
  Store normal(StoreOptions{.path = dir.file("n.db")});
  EXPECT_EQ(normal.synchronous_mode(), 1) << "NORMAL is the default";
}

}  // namespace
}  // namespace fleetgw::storage
