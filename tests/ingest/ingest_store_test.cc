// IngestStore against a real PostgreSQL (a private cluster started by the test): migrations,
// idempotent inserts on (vehicle_id, store_id, sequence), gap tracking reconciled with eviction
// reports, a wiped store (new store_id) beside the old one. Skipped when PostgreSQL is absent.
#include "gateway/ingest/ingest_store.h"

#include <gtest/gtest.h>

#include <memory>
#include <optional>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/ingest/migrations.h"
#include "tests/ingest/pg_fixture.h"

namespace {

using fleetgw::ingest::Decoded;
using fleetgw::ingest::IngestStore;
using fleetgw::ingest::PgConnection;
using fleetgw::testing::PostgresCluster;
namespace v1 = fleetgw::v1;

class IngestStoreTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (fleetgw::testing::postgres_bin_dir().empty()) return;
    cluster_ = std::make_unique<PostgresCluster>();
  }
  static void TearDownTestSuite() { cluster_.reset(); }
  void SetUp() override {
    if (!cluster_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
    PgConnection c(cluster_->conninfo());
    // Each test starts from an empty database: drop everything the migrations made.
    c.exec("DROP SCHEMA public CASCADE; CREATE SCHEMA public", "reset");
  }

  static Decoded record(const std::string& vehicle, const std::string& store, std::uint64_t seq) {
    v1::Envelope e;
    e.set_vehicle_id(vehicle);
    e.set_store_id(store);
    e.set_sequence(seq);
    e.mutable_fault()->set_node("mc");
    e.mutable_fault()->set_name("overheat");
    auto r = fleetgw::ingest::decode_message("fleet/v1", "fleet/v1/" + vehicle + "/fault",
                                             e.SerializeAsString());
    return std::get<Decoded>(r);
  }

  static std::int64_t count(const std::string& sql) {
    PgConnection c(cluster_->conninfo());
    return c.exec(sql, "count").int64(0, 0);
  }

  static std::unique_ptr<PostgresCluster> cluster_;
};
std::unique_ptr<PostgresCluster> IngestStoreTest::cluster_;

TEST_F(IngestStoreTest, MigrationsApplyOnceAndAreRecorded) {
  IngestStore a(cluster_->conninfo(), 100);
  EXPECT_EQ(a.connect(), static_cast<int>(fleetgw::ingest::migrations().size()));
  IngestStore b(cluster_->conninfo(), 100);
  EXPECT_EQ(b.connect(), 0);
  EXPECT_EQ(count("SELECT count(*) FROM schema_migrations"),
            static_cast<std::int64_t>(fleetgw::ingest::migrations().size()));
}

TEST_F(IngestStoreTest, NewerDatabaseIsRefused) {
  IngestStore a(cluster_->conninfo(), 100);
  a.connect();
  PgConnection(cluster_->conninfo())
      .exec("INSERT INTO schema_migrations (version, name) VALUES (999, 'future')", "future");
  IngestStore b(cluster_->conninfo(), 100);
  EXPECT_THROW(b.connect(), fleetgw::ingest::PgError);
}

TEST_F(IngestStoreTest, RedeliveryIsIgnoredAndCounted) {
  IngestStore s(cluster_->conninfo(), 100);
  EXPECT_EQ(s.write(record("b1", "s1", 1)).inserted, 1);
  const auto again = s.write(record("b1", "s1", 1));
  EXPECT_EQ(again.inserted, 0);
  EXPECT_EQ(again.duplicates, 1);
  EXPECT_EQ(count("SELECT count(*) FROM fault_events"), 1);
}

TEST_F(IngestStoreTest, GapsAreHolesNotExplainedByEvictions) {
  IngestStore s(cluster_->conninfo(), 2);  // 2 rows per statement: several statements
  for (std::uint64_t seq : {1, 2, 3, 7, 8, 12}) s.write(record("b1", "s1", seq));
  auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 2u);
  EXPECT_EQ(gaps[0].first_missing, 4);
  EXPECT_EQ(gaps[0].last_missing, 6);
  EXPECT_EQ(gaps[1].first_missing, 9);
  EXPECT_EQ(gaps[1].last_missing, 11);
  EXPECT_EQ(count("SELECT count(*) FROM sequence_ranges"), 3);

  // The gateway evicted 4..6 and says so in record 13: that hole is explained.
  v1::Envelope e;
  e.set_vehicle_id("b1");
  e.set_store_id("s1");
  e.set_sequence(13);
  e.mutable_eviction()->set_first_sequence(4);
  e.mutable_eviction()->set_last_sequence(6);
  e.mutable_eviction()->set_evicted_records(3);
  s.write(std::get<Decoded>(
      fleetgw::ingest::decode_message("fleet/v1", "fleet/v1/b1/eviction", e.SerializeAsString())));
  gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].first_missing, 9);
  // The late records arrive: no gap, one range.
  for (std::uint64_t seq : {11, 9, 10}) s.write(record("b1", "s1", seq));
  EXPECT_TRUE(s.gaps().empty());
  EXPECT_EQ(count("SELECT count(*) FROM sequence_ranges"), 1);
}

TEST_F(IngestStoreTest, LeadingHoleIsAGap) {
  IngestStore s(cluster_->conninfo(), 100);
  s.write(record("b1", "s1", 3));
  const auto gaps = s.gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].first_missing, 1);
  EXPECT_EQ(gaps[0].last_missing, 2);
}

TEST_F(IngestStoreTest, WipedStoreDoesNotCollideWithItsEarlierRows) {
  IngestStore s(cluster_->conninfo(), 100);
  for (std::uint64_t seq : {1, 2}) s.write(record("b1", "old-store", seq));
  for (std::uint64_t seq : {1, 2}) EXPECT_EQ(s.write(record("b1", "new-store", seq)).inserted, 1);
  EXPECT_EQ(count("SELECT count(*) FROM fault_events WHERE vehicle_id = 'b1'"), 4);
  EXPECT_TRUE(s.gaps().empty());
}

TEST_F(IngestStoreTest, RejectIsStoredWithItsReason) {
  IngestStore s(cluster_->conninfo(), 100);
  s.write_reject("fleet/v1/b1/ride\x1b[31m", {"not_an_envelope", "3 bytes"}, 3);
  PgConnection c(cluster_->conninfo());
  const auto r = c.exec("SELECT topic, reason FROM rejected_messages", "rejects");
  ASSERT_EQ(r.rows(), 1);
  EXPECT_EQ(r.text(0, 0), "fleet/v1/b1/ride\\x1b[31m");
  EXPECT_EQ(r.text(0, 1), "not_an_envelope: 3 bytes");
}

}  // namespace
