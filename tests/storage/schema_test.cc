// Schema creation and migrations: from an empty file, from every earlier version (built with the
// real historical migration steps), and refusal of a database newer than this binary.
#include "storage/schema.h"

#include <gtest/gtest.h>

#include <set>

#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using testing::TempDir;

std::set<std::string> objects(Database& db, const std::string& type) {
  std::set<std::string> out;
  Statement st = db.prepare("SELECT name FROM sqlite_master WHERE type = ?");
  st.bind(1, type);
  while (st.step()) {
    std::string name = st.column_text(0);
    if (!name.starts_with("sqlite_")) out.insert(name);
  }
  return out;
}

const std::set<std::string> kCurrentTables = {"rides",      "fault_events",      "pack_snapshots",
                                              "telemetry",  "lock_events",       "command_results",
                                              "commands",   "seen_command_ids",  "meta",
                                              "outbox",     "eviction_counters", "alarms",
                                              "zone_events"};

TEST(Schema, FreshDatabaseGetsCurrentSchema) {
  TempDir dir;
  const std::string path = dir.file("fresh.db");
  { Store store(StoreOptions{.path = path}); }
  Database db(path);
  EXPECT_EQ(schema_version(db), kSchemaVersion);
  EXPECT_EQ(objects(db, "table"), kCurrentTables);
  // v7 dropped outbox_by_source: eviction finds queued entries through outbox_by_priority.
  EXPECT_EQ(objects(db, "index"),
            (std::set<std::string>{"outbox_by_priority", "alarms_by_time", "zone_events_by_time"}));
  EXPECT_EQ(db.query_text("PRAGMA journal_mode"), "wal");
  EXPECT_EQ(db.query_int64("PRAGMA auto_vacuum"), 2) << "INCREMENTAL needed to reclaim space";
}

// Builds a database at each historical version with the genuine migration steps, fills it the
// way that version could, then opens it with the current Store.
class MigrateFrom : public ::testing::TestWithParam<int> {};

TEST_P(MigrateFrom, EarlierVersionUpgradesKeepingData) {
  const int from = GetParam();
  TempDir dir;
  const std::string path = dir.file("old.db");
  {
    Database db(path);
    migrate(db, from);
    ASSERT_EQ(schema_version(db), from);
    // Data every version since v1 can hold: a queued fault and the sequence counter.
    db.exec(
        "INSERT INTO fault_events (node, bit, code, name, severity, event, first_seen_us, "
        "last_seen_us, occurrences) VALUES (1, 3, 1003, 'hall', 'error', 'raised', 10, 10, 1);"
        "INSERT INTO outbox (seq, priority, kind, created_us, payload, source_id) "
        "VALUES (41, 1, 'fault', 10, x'0102', 1);"
        "INSERT INTO meta (key, value) VALUES ('storage.next_seq', '42');"
        "INSERT INTO rides (ride_id, state, start_us) VALUES ('r-open', 'open', 5);");
  }
  Store store(StoreOptions{.path = path});
  {
    Database db(path);
    EXPECT_EQ(schema_version(db), kSchemaVersion);
    EXPECT_EQ(objects(db, "table"), kCurrentTables);
    EXPECT_EQ(db.query_int64("SELECT count(*) FROM eviction_counters"), 3);
  }
  auto entries = store.peek_outbox(10, 1 << 20);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].seq, 41u);
  EXPECT_EQ(entries[0].kind, OutboxKind::kFault);
  EXPECT_EQ(entries[0].payload, (Bytes{1, 2}));
  EXPECT_EQ(store.next_seq(), 42u);
  ASSERT_EQ(store.open_rides().size(), 1u);
  EXPECT_EQ(store.open_rides()[0].ride_id, "r-open");

  Batch b;
  b.now_us = 20;
  b.telemetry.push_back({testing::telemetry_at(20), testing::payload_of("t")});
  auto r = store.write(b);
  ASSERT_TRUE(r.ok()) << r.status().message;
  EXPECT_EQ(r->first_seq, 42u);
}

INSTANTIATE_TEST_SUITE_P(EveryEarlierVersion, MigrateFrom, ::testing::Range(1, kSchemaVersion),
                         [](const auto& info) { return "v" + std::to_string(info.param); });

TEST(Schema, EmptyFileMigratesStepByStep) {
  TempDir dir;
  Database db(dir.file("steps.db"));
  EXPECT_EQ(migrate(db, 1), 0);
  EXPECT_EQ(schema_version(db), 1);
  EXPECT_EQ(objects(db, "index"), std::set<std::string>{}) << "v1 had no outbox indexes";
  EXPECT_EQ(migrate(db), 1);
  EXPECT_EQ(schema_version(db), kSchemaVersion);
  EXPECT_EQ(migrate(db), kSchemaVersion) << "migrating a current database is a no-op";
}

TEST(Schema, AutoVacuumAppliedEvenAfterHeaderWasWritten) {
  TempDir dir;
  Database db(dir.file("wal-first.db"));
  EXPECT_EQ(db.query_text("PRAGMA journal_mode = WAL"), "wal");  // writes page 1
  migrate(db);
  EXPECT_EQ(db.query_int64("PRAGMA auto_vacuum"), 2);
}

TEST(Schema, NewerDatabaseIsRefusedWithPathAndVersions) {
  TempDir dir;
  const std::string path = dir.file("future.db");
  {
    Database db(path);
    migrate(db);
    db.exec("PRAGMA user_version = " + std::to_string(kSchemaVersion + 7));
  }
  try {
    Store store(StoreOptions{.path = path});
    FAIL() << "a newer schema must stop start-up";
  } catch (const SchemaTooNewError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find("version " + std::to_string(kSchemaVersion + 7)), std::string::npos) << msg;
    EXPECT_NE(msg.find("at most " + std::to_string(kSchemaVersion)), std::string::npos) << msg;
    EXPECT_EQ(e.found_version(), kSchemaVersion + 7);
    EXPECT_EQ(e.supported_version(), kSchemaVersion);
  }
  // Refused, not "repaired": the file is still there, untouched.
  Database db(path);
  EXPECT_EQ(schema_version(db), kSchemaVersion + 7);
  EXPECT_FALSE(std::filesystem::exists(path + ".corrupt"));
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(e.path().string().find(".corrupt-"), std::string::npos) << e.path();
  }
}

// v3: the command journal keeps the digest of the signed command bytes. A v2 journal row
// survives the migration with no digest; new rows keep theirs, and a state update that carries
// no digest does not erase the stored one.
TEST(Schema, V2JournalRowsOpenWithoutDigestAndNewRowsKeepTheirs) {
  TempDir dir;
  const std::string path = dir.file("v2.db");
  {
    Database db(path);
    migrate(db, 2);
    db.exec(
        "INSERT INTO commands (command_id, received_us, state, expires_at_us) "
        "VALUES ('old-cmd', 10, 'executing', 1000)");
  }
  Store store(StoreOptions{.path = path});
  const auto old = store.command("old-cmd");
  ASSERT_TRUE(old.has_value());
  EXPECT_EQ(old->state, "executing");
  EXPECT_TRUE(old->command_sha256.empty());

  const std::string digest(32, '\xA5');
  Batch b;
  b.now_us = 20;
  b.commands.push_back({"new-cmd", 20, "executing", 2000, digest});
  ASSERT_TRUE(store.write(b).ok());
  EXPECT_EQ(store.command("new-cmd")->command_sha256, digest);

  Batch update;
  update.now_us = 30;
  update.commands.push_back({"new-cmd", 20, "succeeded", 2000, {}});
  ASSERT_TRUE(store.write(update).ok());
  const auto updated = store.command("new-cmd");
  EXPECT_EQ(updated->state, "succeeded");
  EXPECT_EQ(updated->command_sha256, digest) << "an update without a digest keeps it";
}

TEST(Schema, MigrateRejectsBadTarget) {
  TempDir dir;
  Database db(dir.file("x.db"));
  EXPECT_THROW(migrate(db, kSchemaVersion + 1), std::invalid_argument);
  migrate(db);
  EXPECT_THROW(migrate(db, 1), std::invalid_argument);
}

}  // namespace
}  // namespace fleetgw::storage
