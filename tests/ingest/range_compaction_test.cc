// Sequence ranges appended per batch and compacted later (migration 11, ingest_store.h):
// the gap report exact over unmerged rows (adjacent, overlapping, out of order, duplicated,
// 2^63-1) and the same after a compaction; appends committed while a compaction runs kept;
// writers and compactions at once losing nothing; a database of migration 10 keeping every
// range and gap. Real PostgreSQL (pg_fixture.h); skipped when it is absent.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "backend/ingest/ingest_store.h"
#include "backend/ingest/migrations.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::PgConnection;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::Gap;
using fleetgw::ingest::IngestStore;
using fleetgw::testing::decoded;
using fleetgw::testing::PgDatabaseTest;
namespace v1 = fleetgw::v1;

constexpr std::int64_t kTop = std::numeric_limits<std::int64_t>::max();

class RangeCompactionTest : public PgDatabaseTest {
 protected:
  static Decoded fault_record(const std::string& vehicle, const std::string& store,
                              std::int64_t seq) {
    v1::Envelope e;
    e.set_vehicle_id(vehicle);
    e.set_store_id(store);
    e.set_sequence(static_cast<std::uint64_t>(seq));
    e.mutable_fault()->set_node("mc");
    e.mutable_fault()->set_name("overheat");
    return decoded(e, "fault");
  }
  // Each sequence one message, all in one batch (one transaction).
  static void write_batch(IngestStore& s, const std::string& vehicle,
                          const std::vector<std::int64_t>& seqs) {
    std::vector<Decoded> ds;
    ds.reserve(seqs.size());
    for (std::int64_t q : seqs) ds.push_back(fault_record(vehicle, "s1", q));
    std::vector<const Decoded*> ptrs;
    for (const Decoded& d : ds) ptrs.push_back(&d);
    const auto r = s.write_batch(ptrs);
    for (const auto& refused : r.refused) ASSERT_FALSE(refused.has_value());
  }
  // The view sequence_ranges as "vehicle:first-last ..." in order.
  static std::string ranges() {
    return text(
        "SELECT coalesce(string_agg(vehicle_id || ':' || first_seq || '-' || last_seq, ' ' "
        "ORDER BY vehicle_id, first_seq), '') FROM sequence_ranges");
  }
  static std::string gap_text(const std::vector<Gap>& gaps) {
    std::string out;
    for (const Gap& g : gaps) {
      out += (out.empty() ? "" : " ") + g.vehicle_id + ":" + std::to_string(g.first_missing) + "-" +
             std::to_string(g.last_missing);
    }
    return out;
  }
};

// Batches whose ranges arrive out of order, overlap (a redelivery), touch and sit at the top of
// bigint, never compacted: the view and the gap report are exact over the unmerged rows, and
// the same after one compaction (which leaves one row per island).
TEST_F(RangeCompactionTest, GapReportIsExactOverUnmergedRangesAndAfterCompaction) {
  IngestStore s(conninfo());
  s.connect();
  write_batch(s, "b1", {10, 11, 12});
  write_batch(s, "b1", {3, 4});        // before the first: out of order
  write_batch(s, "b1", {11, 12, 13});  // overlaps (a redelivery of 11 and 12)
  write_batch(s, "b1", {5});           // touches 3-4 on the right
  write_batch(s, "b1", {20});          // an island
  write_batch(s, "b1", {kTop - 1});    // near the top...
  write_batch(s, "b1", {kTop});        // ...and at it, touching
  write_batch(s, "b2", {1, 2});
  write_batch(s, "b2", {1, 2});                                     // a duplicate range
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 9);  // nothing merged yet
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_merged"), 0);
  const std::string want_ranges = "b1:3-5 b1:10-13 b1:20-20 b1:" + std::to_string(kTop - 1) + "-" +
                                  std::to_string(kTop) + " b2:1-2";
  const std::string want_gaps = "b1:1-2 b1:6-9 b1:14-19 b1:21-" + std::to_string(kTop - 2);
  EXPECT_EQ(ranges(), want_ranges);
  EXPECT_EQ(gap_text(s.gaps()), want_gaps);

  EXPECT_EQ(s.compact_ranges(), 9);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 0);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_merged"), 5);
  EXPECT_EQ(ranges(), want_ranges);
  EXPECT_EQ(gap_text(s.gaps()), want_gaps);

  // Appended rows beside merged ones: filling 6-9 and 14-19 joins three merged ranges.
  write_batch(s, "b1", {6, 7, 8, 9, 14, 15, 16, 17, 18, 19});
  EXPECT_EQ(ranges(),
            "b1:3-20 b1:" + std::to_string(kTop - 1) + "-" + std::to_string(kTop) + " b2:1-2");
  EXPECT_EQ(s.compact_ranges(), 2);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_merged"), 3);
  EXPECT_EQ(gap_text(s.gaps()), "b1:1-2 b1:21-" + std::to_string(kTop - 2));
}

// write_batch compacts by itself once this store appended enough ranges.
TEST_F(RangeCompactionTest, BatchesCompactAfterTheirThreshold) {
  IngestStore s(conninfo());
  s.connect();
  s.set_compaction(3, std::chrono::hours(1));
  write_batch(s, "b1", {1, 2});
  write_batch(s, "b1", {4});
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 2);  // 2 ranges: below 3
  write_batch(s, "b1", {3});
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 0);
  EXPECT_EQ(text("SELECT string_agg(first_seq || '-' || last_seq, ' ') FROM "
                 "sequence_ranges_merged"),
            "1-4");
}

// A batch that commits while a compaction runs keeps its ranges: the compaction deletes only
// the appended rows its statement saw (not every row of the table at its end), and does not
// wait for the batch. (A compaction that emptied the table, e.g. by TRUNCATE, would wait for
// the batch's commit and then drop its range: 11-20 lost, a gap reported.)
TEST_F(RangeCompactionTest, AppendsCommittedDuringACompactionAreKept) {
  IngestStore s(conninfo());
  s.connect();
  write_batch(s, "b1", {1, 2, 3});
  PgConnection batch(conninfo());
  batch.exec("BEGIN", "begin");
  batch.exec("INSERT INTO sequence_ranges_new VALUES ('b1', 's1', 4, 20)", "append");
  std::atomic<bool> done{false};
  std::int64_t moved = -1;
  std::thread compactor([&] {
    IngestStore c(conninfo());
    moved = c.compact_ranges();
    done = true;
  });
  // The compaction finished, or waits for the open batch (then the commit below releases it).
  PgConnection watch(conninfo());
  const bool settled = fleetgw::testing::wait_until(
      [&] {
        return done.load() ||
               watch.exec(
                        "SELECT count(*) FROM pg_stat_activity WHERE wait_event_type = "
                        "'Lock' AND pid <> pg_backend_pid()",
                        "lock waits")
                       .int64(0, 0) > 0;
      },
      std::chrono::seconds(30));
  batch.exec("COMMIT", "commit");
  compactor.join();
  ASSERT_TRUE(settled);
  EXPECT_EQ(moved, 1);  // the committed range 1-3 only
  EXPECT_EQ(ranges(), "b1:1-20");
  EXPECT_TRUE(s.gaps().empty());
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 1);  // left for the next one
  EXPECT_EQ(s.compact_ranges(), 1);
  EXPECT_EQ(text("SELECT string_agg(first_seq || '-' || last_seq, ' ') FROM "
                 "sequence_ranges_merged"),
            "1-20");
}

// Two writers on one vehicle (interleaved sequences, one transaction per message) while a third
// connection compacts in a loop: every sequence accounted, one range, no gap.
TEST_F(RangeCompactionTest, WritersAndCompactionsAtOnceLoseNoRange) {
  IngestStore setup(conninfo());
  setup.connect();
  constexpr std::int64_t kLast = 300;
  std::atomic<int> writing{2};
  std::atomic<bool> compacting{false};
  auto writer = [&](std::int64_t parity) {
    IngestStore w(conninfo());
    w.connect();
    // From the compactor's first turn on, so that the two overlap whatever the machine's load.
    fleetgw::testing::wait_until([&] { return compacting.load(); }, std::chrono::seconds(60));
    for (std::int64_t q = 1 + parity; q <= kLast; q += 2) w.write(fault_record("b1", "s1", q));
    --writing;
  };
  std::int64_t compactions = 0;
  std::thread compactor([&] {
    IngestStore c(conninfo());
    while (writing.load() > 0) {
      c.compact_ranges();
      ++compactions;
      compacting = true;
    }
  });
  std::thread odd(writer, 0);
  std::thread even(writer, 1);
  odd.join();
  even.join();
  compactor.join();
  EXPECT_GE(compactions, 1);
  EXPECT_EQ(ranges(), "b1:1-" + std::to_string(kLast));
  EXPECT_TRUE(setup.gaps().empty());
  setup.compact_ranges();
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_new"), 0);
  EXPECT_EQ(text("SELECT string_agg(first_seq || '-' || last_seq, ' ') FROM "
                 "sequence_ranges_merged"),
            "1-" + std::to_string(kLast));
}

// A database of migration 10 with merged ranges (a gap between two, one at the top of bigint):
// migrated, its ranges and gap report are as before, and new batches merge with them.
TEST_F(RangeCompactionTest, MigrationElevenKeepsEveryRangeAndGap) {
  migrate_up_to(10);
  const std::string old_ranges =
      "('b1', 's1', 1, 5), ('b1', 's1', 9, 10), ('b2', 's1', 3, " + std::to_string(kTop) + ")";
  {
    PgConnection c(conninfo());
    c.exec("INSERT INTO sequence_ranges VALUES " + old_ranges, "old ranges");
  }
  const std::string gaps_sql =
      "SELECT string_agg(vehicle_id || ':' || first_missing || '-' || last_missing, ' ' ORDER BY "
      "vehicle_id, first_missing) FROM sequence_gaps";
  const std::string before_gaps = text(gaps_sql);
  EXPECT_EQ(before_gaps, "b1:6-8 b2:1-2");
  const std::string before_ranges = ranges();

  IngestStore s(conninfo());
  EXPECT_EQ(s.connect(), 1);
  EXPECT_EQ(ranges(), before_ranges);
  EXPECT_EQ(text(gaps_sql), before_gaps);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_merged"), 3);

  write_batch(s, "b1", {6, 7, 8});
  EXPECT_EQ(ranges(), "b1:1-10 b2:3-" + std::to_string(kTop));
  EXPECT_EQ(s.compact_ranges(), 1);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges_merged"), 2);
  EXPECT_EQ(gap_text(s.gaps()), "b2:1-2");
}

}  // namespace
