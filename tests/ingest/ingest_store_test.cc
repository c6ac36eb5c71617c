// IngestStore against a real PostgreSQL (a private cluster started by the test): migrations,
// idempotent inserts on (vehicle_id, store_id, sequence), gap tracking reconciled with eviction
// reports, a wiped store (new store_id) beside the old one. Skipped when PostgreSQL is absent.
#include "backend/ingest/ingest_store.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "backend/ingest/migrations.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"

namespace {

using fleetgw::PgConnection;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::IngestStore;
using fleetgw::testing::decoded;
using fleetgw::testing::PgDatabaseTest;
namespace v1 = fleetgw::v1;

class IngestStoreTest : public PgDatabaseTest {
 protected:
  static Decoded record(const std::string& vehicle, const std::string& store, std::uint64_t seq) {
    v1::Envelope e;
    e.set_vehicle_id(vehicle);
    e.set_store_id(store);
    e.set_sequence(seq);
    e.mutable_fault()->set_node("mc");
    e.mutable_fault()->set_name("overheat");
    return decoded(e, "fault");
  }
};

TEST_F(IngestStoreTest, MigrationsApplyOnceAndAreRecorded) {
  IngestStore a(conninfo(), 100);
  EXPECT_EQ(a.connect(), static_cast<int>(fleetgw::ingest::migrations().size()));
  IngestStore b(conninfo(), 100);
  EXPECT_EQ(b.connect(), 0);
  EXPECT_EQ(int64("SELECT count(*) FROM schema_migrations"),
            static_cast<std::int64_t>(fleetgw::ingest::migrations().size()));
}

// A database a v1-only ingest made (with a row in it) is brought to the newest version once,
// keeping its rows; the status table gains the refusal columns (NULL in the old row).
TEST_F(IngestStoreTest, MigrationTwoAppliesOnceOnAVersionOneDatabase) {
  {
    migrate_up_to(1);
    PgConnection c(conninfo());
    c.exec(
        "INSERT INTO status (vehicle_id, created_at_us, online, connection, bus_state, "
        "firmware_version, last_will, attention) VALUES ('b0', 1, 'ONLINE_STATE_ONLINE', 'c', "
        "'b', '1.3', false, '{}')",
        "old status");
  }
  IngestStore a(conninfo(), 100);
  EXPECT_EQ(a.connect(), static_cast<int>(fleetgw::ingest::migrations().size()) - 1);
  IngestStore b(conninfo(), 100);
  EXPECT_EQ(b.connect(), 0);
  EXPECT_EQ(int64("SELECT max(version) FROM schema_migrations"),
            fleetgw::ingest::migrations().back().version);
  EXPECT_EQ(int64("SELECT count(*) FROM status WHERE vehicle_id = 'b0' AND publish_refusals IS "
                  "NULL"),
            1);
  EXPECT_EQ(int64("SELECT count(*) FROM zone_events"), 0);
}

TEST_F(IngestStoreTest, ZoneEventIsStoredOnceDespiteRedelivery) {
  IngestStore s(conninfo(), 100);
  v1::Envelope e;
  e.set_vehicle_id("b1");
  e.set_store_id("s1");
  e.set_sequence(4);
  e.set_created_at_us(1'700'000'000'000'000);
  v1::ZoneEvent* z = e.mutable_zone();
  z->set_zone_id("depot");
  z->set_zone_name("Depot");
  z->set_kind(v1::ZONE_KIND_OPERATING_AREA);
  z->set_transition(v1::ZONE_TRANSITION_EXIT);
  z->set_at_us(1'700'000'000'000'100);
  z->mutable_position()->set_lat_e7(483'000'001);
  z->mutable_position()->set_lon_e7(-2'000'002);
  z->set_bundle_version(9);
  const auto msg = [&] { return decoded(e, "zone"); };
  EXPECT_EQ(s.write(msg()).inserted, 1);
  const auto again = s.write(msg());
  EXPECT_EQ(again.inserted, 0);
  EXPECT_EQ(again.duplicates, 1);
  PgConnection c(conninfo());
  const auto r = c.exec(
      "SELECT zone_id, zone_name, kind, transition, at_us, lat_e7, lon_e7, bundle_version "
      "FROM zone_events",
      "zone rows");
  ASSERT_EQ(r.rows(), 1);
  EXPECT_EQ(r.text(0, 0), "depot");
  EXPECT_EQ(r.text(0, 1), "Depot");
  EXPECT_EQ(r.text(0, 2), "ZONE_KIND_OPERATING_AREA");
  EXPECT_EQ(r.text(0, 3), "ZONE_TRANSITION_EXIT");
  EXPECT_EQ(r.int64(0, 4), 1'700'000'000'000'100);
  EXPECT_EQ(r.int64(0, 5), 483'000'001);
  EXPECT_EQ(r.int64(0, 6), -2'000'002);
  EXPECT_EQ(r.int64(0, 7), 9);
  // The zone event accounts for its sequence: 1..3 are a gap, nothing else.
  const auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].last_missing, 3);

  // docs/backend.md's "zone entries per zone per day" query, as printed there.
  e.set_sequence(5);
  z->set_transition(v1::ZONE_TRANSITION_ENTER);
  EXPECT_EQ(s.write(msg()).inserted, 1);
  const auto per_day = c.exec(
      "SELECT date_trunc('day', to_timestamp(at_us / 1e6)) AS day, zone_id, "
      "min(zone_name) AS zone_name, count(*) AS entries, count(DISTINCT vehicle_id) AS vehicles "
      "FROM zone_events WHERE transition = 'ZONE_TRANSITION_ENTER' "
      "GROUP BY 1, 2 ORDER BY 1, entries DESC",
      "zone entries per day");
  ASSERT_EQ(per_day.rows(), 1);
  EXPECT_EQ(per_day.text(0, 1), "depot");
  EXPECT_EQ(per_day.int64(0, 3), 1);
}

TEST_F(IngestStoreTest, AlarmAndStatusOfSchemaOnePointFourLand) {
  IngestStore s(conninfo(), 100);
  v1::Envelope alarm;
  alarm.set_vehicle_id("b1");
  alarm.set_store_id("s1");
  alarm.set_sequence(1);
  alarm.mutable_alarm()->set_kind(v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  s.write(decoded(alarm, "alarm"));
  v1::Envelope status;
  status.set_vehicle_id("b1");
  status.mutable_status()->set_publish_refusals(2);
  status.mutable_status()->set_last_publish_refusal("not authorized");
  status.mutable_status()->set_last_publish_refusal_code(135);
  status.mutable_status()->set_last_publish_refusal_at_us(77);
  const auto write_status = [&] { s.write(decoded(status, "status")); };
  write_status();
  status.mutable_status()->set_publish_refusals(5);  // the upsert replaces the count
  write_status();
  EXPECT_EQ(int64("SELECT count(*) FROM alarms WHERE kind = 'ALARM_KIND_OUTSIDE_OPERATING_AREA'"),
            1);
  PgConnection c(conninfo());
  const auto r = c.exec(
      "SELECT publish_refusals, last_publish_refusal, last_publish_refusal_code, "
      "last_publish_refusal_at_us FROM status",
      "status");
  ASSERT_EQ(r.rows(), 1);
  EXPECT_EQ(r.int64(0, 0), 5);
  EXPECT_EQ(r.text(0, 1), "not authorized");
  EXPECT_EQ(r.int64(0, 2), 135);
  EXPECT_EQ(r.int64(0, 3), 77);
}

TEST_F(IngestStoreTest, NewerDatabaseIsRefused) {
  IngestStore a(conninfo(), 100);
  a.connect();
  PgConnection(conninfo())
      .exec("INSERT INTO schema_migrations (version, name) VALUES (999, 'future')", "future");
  IngestStore b(conninfo(), 100);
  EXPECT_THROW(b.connect(), fleetgw::PgError);
}

TEST_F(IngestStoreTest, RedeliveryIsIgnoredAndCounted) {
  IngestStore s(conninfo(), 100);
  EXPECT_EQ(s.write(record("b1", "s1", 1)).inserted, 1);
  const auto again = s.write(record("b1", "s1", 1));
  EXPECT_EQ(again.inserted, 0);
  EXPECT_EQ(again.duplicates, 1);
  EXPECT_EQ(int64("SELECT count(*) FROM fault_events"), 1);
}

TEST_F(IngestStoreTest, GapsAreHolesNotExplainedByEvictions) {
  IngestStore s(conninfo(), 2);  // 2 rows per statement: several statements
  for (std::uint64_t seq : {1, 2, 3, 7, 8, 12}) s.write(record("b1", "s1", seq));
  auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 2u);
  EXPECT_EQ(gaps[0].first_missing, 4);
  EXPECT_EQ(gaps[0].last_missing, 6);
  EXPECT_EQ(gaps[1].first_missing, 9);
  EXPECT_EQ(gaps[1].last_missing, 11);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges"), 3);

  // The gateway evicted 4..6 and says so in record 13: that hole is explained.
  v1::Envelope e;
  e.set_vehicle_id("b1");
  e.set_store_id("s1");
  e.set_sequence(13);
  e.mutable_eviction()->set_first_sequence(4);
  e.mutable_eviction()->set_last_sequence(6);
  e.mutable_eviction()->set_evicted_records(3);
  s.write(decoded(e, "eviction"));
  gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].first_missing, 9);
  // The late records arrive: no gap, one range.
  for (std::uint64_t seq : {11, 9, 10}) s.write(record("b1", "s1", seq));
  EXPECT_TRUE(s.gaps().empty());
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges"), 1);
}

TEST_F(IngestStoreTest, LeadingHoleIsAGap) {
  IngestStore s(conninfo(), 100);
  s.write(record("b1", "s1", 3));
  const auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].first_missing, 1);
  EXPECT_EQ(gaps[0].last_missing, 2);
}

TEST_F(IngestStoreTest, WipedStoreDoesNotCollideWithItsEarlierRows) {
  IngestStore s(conninfo(), 100);
  for (std::uint64_t seq : {1, 2}) s.write(record("b1", "old-store", seq));
  for (std::uint64_t seq : {1, 2}) EXPECT_EQ(s.write(record("b1", "new-store", seq)).inserted, 1);
  EXPECT_EQ(int64("SELECT count(*) FROM fault_events WHERE vehicle_id = 'b1'"), 4);
  EXPECT_TRUE(s.gaps().empty());
}

TEST_F(IngestStoreTest, RejectIsStoredWithItsReason) {
  IngestStore s(conninfo(), 100);
  s.write_reject("fleet/v1/b1/ride\x1b[31m", {"not_an_envelope", "3 bytes"}, 3);
  PgConnection c(conninfo());
  const auto r = c.exec("SELECT topic, reason FROM rejected_messages", "rejects");
  ASSERT_EQ(r.rows(), 1);
  EXPECT_EQ(r.text(0, 0), "fleet/v1/b1/ride\\x1b[31m");
  EXPECT_EQ(r.text(0, 1), "not_an_envelope: 3 bytes");
}

// Issue 24: a VehicleState stamped far in the future (a gateway's wrong clock) must not freeze
// the vehicle's state: later real ones replace it. An older state after a real one is still
// out of order, and counted as such (not as a duplicate).
TEST_F(IngestStoreTest, StateFromTheFutureIsReplacedByLaterRealOnes) {
  IngestStore s(conninfo());
  const auto state = [](std::int64_t at_us, std::uint32_t soc) {
    v1::Envelope e;
    e.set_vehicle_id("b1");
    e.mutable_state()->set_updated_at_us(at_us);
    e.mutable_state()->set_soc_pct(soc);
    return decoded(e, "state");
  };
  const std::int64_t now = std::chrono::duration_cast<std::chrono::microseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  constexpr std::int64_t kYearUs = 365LL * 24 * 3600 * 1'000'000;
  s.write(state(now + 10 * kYearUs, 10));
  EXPECT_EQ(s.write(state(now, 50)).stale_states, 0);
  EXPECT_EQ(int64("SELECT soc_pct FROM vehicle_state WHERE vehicle_id = 'b1'"), 50);
  const auto late = s.write(state(now - 1'000'000, 20));
  EXPECT_EQ(late.stale_states, 1);
  EXPECT_EQ(late.duplicates, 0);
  EXPECT_EQ(int64("SELECT soc_pct FROM vehicle_state WHERE vehicle_id = 'b1'"), 50);
}

// Issue 24: the docs allow sequences up to 2^63-1; the range bookkeeping must not overflow.
TEST_F(IngestStoreTest, SequenceAtTheTopOfBigintIsAccounted) {
  IngestStore s(conninfo());
  constexpr auto kMax = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(s.write(record("b1", "s1", kMax)).inserted, 1);
  EXPECT_EQ(s.write(record("b1", "s1", kMax - 1)).inserted, 1);
  EXPECT_EQ(s.write(record("b1", "s1", kMax)).duplicates, 1);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges"), 1);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges WHERE last_seq = 9223372036854775807 "
                  "AND first_seq = 9223372036854775806"),
            1);
  const auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].first_missing, 1);
  EXPECT_EQ(gaps[0].last_missing, std::numeric_limits<std::int64_t>::max() - 2);
}

// Issue 24: a status attention text is stored exactly as sent (a newline, quotes, backslashes).
TEST_F(IngestStoreTest, AttentionTextIsStoredAsSent) {
  IngestStore s(conninfo());
  v1::Envelope e;
  e.set_vehicle_id("b1");
  const std::vector<std::string> texts = {"outbox full\nsince 10:00", "say \"hi\" \\o/",
                                          "tab\there, {braces}", ""};
  for (const std::string& t : texts) e.mutable_status()->add_attention(t);
  s.write(decoded(e, "status"));
  PgConnection c(conninfo());
  const auto r = c.exec("SELECT unnest(attention) FROM status WHERE vehicle_id = 'b1'", "att");
  ASSERT_EQ(r.rows(), static_cast<int>(texts.size()));
  for (int i = 0; i < r.rows(); ++i) EXPECT_EQ(r.text(i, 0), texts[i]);
}

// One batch: records (one already stored: a duplicate), two states of one vehicle out of order;
// the counters name each apart.
TEST_F(IngestStoreTest, BatchCountsDuplicatesAndOutOfOrderStatesApart) {
  IngestStore s(conninfo());
  s.write(record("b1", "s1", 1));
  const auto state = [](std::int64_t at_us) {
    v1::Envelope e;
    e.set_vehicle_id("b2");
    e.mutable_state()->set_updated_at_us(at_us);
    return decoded(e, "state");
  };
  const Decoded a = record("b1", "s1", 1), b = record("b1", "s1", 2), c = record("b1", "s1", 3),
                newer = state(2'000), older = state(1'000);
  const Decoded* batch[] = {&a, &b, &c, &newer, &older};
  const auto r = s.write_batch(batch);
  EXPECT_EQ(r.stats.duplicates, 1);
  EXPECT_EQ(r.stats.stale_states, 1);
  EXPECT_EQ(r.stats.inserted, 3);  // two records and one state
  EXPECT_EQ(int64("SELECT updated_at_us FROM vehicle_state WHERE vehicle_id = 'b2'"), 2'000);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges"), 1);
  EXPECT_TRUE(s.gaps().empty());
}

// A batch's ranges that grow a stored range, ones a stored range covers (a redelivery), a new
// store, a range leaving a hole and one bridging two stored ranges, in the same batches: the
// accounted ranges and the gap report stay exact (the merge of kMergeRanges, ingest_store.cc).
TEST_F(IngestStoreTest, MixedRangesOfABatchMergeExactly) {
  IngestStore s(conninfo());
  const auto write =
      [&](const std::vector<std::tuple<std::string, std::uint64_t, std::uint64_t>>& runs) {
        std::vector<Decoded> records;
        for (const auto& [vehicle, first, last] : runs) {
          for (std::uint64_t q = first; q <= last; ++q) records.push_back(record(vehicle, "s1", q));
        }
        std::vector<const Decoded*> batch;
        for (const Decoded& d : records) batch.push_back(&d);
        return s.write_batch(batch).stats;
      };
  const auto ranges = [&] {
    PgConnection c(conninfo());
    const auto r = c.exec(
        "SELECT string_agg(vehicle_id || ':' || first_seq || '-' || last_seq, ' ' ORDER BY "
        "vehicle_id, first_seq) FROM sequence_ranges",
        "ranges");
    return std::string(r.text(0, 0));
  };
  write({{"b1", 1, 10}, {"b1", 20, 30}, {"b3", 1, 5}});
  ASSERT_EQ(ranges(), "b1:1-10 b1:20-30 b3:1-5");
  // Growing: b1 11-12 and 31-35; covered: b1 5 (a redelivery); a new store: b2; a hole: b3 7-8.
  const auto stats =
      write({{"b1", 5, 5}, {"b1", 11, 12}, {"b1", 31, 35}, {"b2", 1, 3}, {"b3", 7, 8}});
  EXPECT_EQ(stats.duplicates, 1);
  EXPECT_EQ(ranges(), "b1:1-12 b1:20-35 b2:1-3 b3:1-5 b3:7-8");
  auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 2u);
  EXPECT_EQ(gaps[0].vehicle_id, "b1");
  EXPECT_EQ(gaps[0].first_missing, 13);
  EXPECT_EQ(gaps[0].last_missing, 19);
  EXPECT_EQ(gaps[1].vehicle_id, "b3");
  EXPECT_EQ(gaps[1].first_missing, 6);
  // b1 13-19 bridges its two ranges, b1 36 grows the upper one in the same batch, b3 9 grows 7-8.
  write({{"b1", 13, 19}, {"b1", 36, 36}, {"b3", 9, 9}});
  EXPECT_EQ(ranges(), "b1:1-36 b2:1-3 b3:1-5 b3:7-9");
  gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].vehicle_id, "b3");
  EXPECT_EQ(int64("SELECT count(*) FROM fault_events"), 36 + 3 + 9 - 1);
}

// committed_at_us is the database's clock as the batch is written, one value for all its rows
// (written by the COPY itself: a per-row volatile default would make the server insert row by
// row, issue 25), between a reading before the batch and one after its commit.
TEST_F(IngestStoreTest, BatchRowsCarryOneCommitStampFromTheDatabaseClock) {
  IngestStore s(conninfo());
  s.connect();
  std::vector<Decoded> faults;
  for (std::uint64_t seq = 1; seq <= 300; ++seq) faults.push_back(record("b1", "s1", seq));
  std::vector<const Decoded*> batch;
  for (const Decoded& d : faults) batch.push_back(&d);
  const std::int64_t before = int64("SELECT fleet_now_us()");
  s.write_batch(batch);
  const std::int64_t after = int64("SELECT fleet_now_us()");
  EXPECT_EQ(int64("SELECT count(*) FROM fault_events"), 300);
  EXPECT_EQ(int64("SELECT count(DISTINCT committed_at_us) FROM fault_events"), 1);
  const std::int64_t stamp = int64("SELECT min(committed_at_us) FROM fault_events");
  EXPECT_GE(stamp, before);
  EXPECT_LE(stamp, after);
  // A redelivery takes the ON CONFLICT path: nothing added, the stored stamp kept.
  EXPECT_EQ(s.write_batch(batch).stats.duplicates, 300);
  EXPECT_EQ(
      int64("SELECT count(*) FROM fault_events WHERE committed_at_us = " + std::to_string(stamp)),
      300);
}

// A database of schema v2 (today's before issue 25) with telemetry over several days, one
// sample without a clock (1970) and other records: migrated to partitioned telemetry, every row
// kept, each day in its partition, and a day's query reads that partition only.
TEST_F(IngestStoreTest, MigrationToPartitionedTelemetryKeepsEveryRow) {
  {
    migrate_up_to(2);
    PgConnection c(conninfo());
    // 3 days x 100 samples, plus one at 1970-01-01.
    c.exec(
        "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
        "sampled_at_us, speed_dkmh) SELECT 'b1', 's1', g, 1, 1700000000000000 + (g / 100) * "
        "86400000000 + g, g FROM generate_series(0, 299) g",
        "old telemetry");
    c.exec(
        "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
        "sampled_at_us) VALUES ('b1', 's1', 1000, 1, 0)",
        "no clock");
    c.exec("INSERT INTO sequence_ranges VALUES ('b1', 's1', 1, 299), ('b1', 's1', 1000, 1000)",
           "ranges");
  }
  IngestStore s(conninfo());
  EXPECT_EQ(s.connect(), static_cast<int>(fleetgw::ingest::migrations().size()) - 2);
  EXPECT_EQ(int64("SELECT count(*) FROM telemetry_samples"), 301);
  EXPECT_EQ(int64("SELECT sum(speed_dkmh) FROM telemetry_samples"), 299 * 300 / 2);
  EXPECT_EQ(int64("SELECT count(*) FROM telemetry_samples_default"), 1);
  EXPECT_EQ(int64("SELECT count(DISTINCT tableoid) FROM telemetry_samples"), 4);
  EXPECT_EQ(int64("SELECT count(*) FROM sequence_ranges"), 2);
  // A redelivered old sample is still a duplicate.
  v1::Envelope e;
  e.set_vehicle_id("b1");
  e.set_store_id("s1");
  v1::TelemetrySample* sample = e.mutable_telemetry()->add_samples();
  sample->set_sequence(5);
  sample->set_sampled_at_us(1700000000000000 + 5);
  EXPECT_EQ(s.write(decoded(e, "telemetry")).duplicates, 1);
  // Partition pruning: a one-day range reads one partition.
  PgConnection c(conninfo());
  const auto plan = c.exec(
      "EXPLAIN SELECT count(*) FROM telemetry_samples WHERE sampled_at_us >= 1700006400000000 "
      "AND sampled_at_us < 1700092800000000",
      "plan");
  std::string text;
  for (int i = 0; i < plan.rows(); ++i) text += std::string(plan.text(i, 0)) + "\n";
  EXPECT_EQ(text.find("telemetry_samples_default"), std::string::npos) << text;
  EXPECT_NE(text.find("telemetry_samples_p"), std::string::npos) << text;
  // Partitions ahead, and retention drops the old days (their rows only).
  EXPECT_EQ(s.maintain_partitions(3, 0), 0);
  EXPECT_GE(int64("SELECT count(*) FROM pg_inherits WHERE inhparent = "
                  "'telemetry_samples'::regclass"),
            4 + 5);
  EXPECT_EQ(s.maintain_partitions(3, 30), 3);
  EXPECT_EQ(int64("SELECT count(*) FROM telemetry_samples"), 1);
}

}  // namespace
