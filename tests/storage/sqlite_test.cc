// The RAII SQLite wrappers: binding and reading every type, transactions, error reporting.
#include "storage/sqlite.h"

#include <gtest/gtest.h>

#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using testing::TempDir;

TEST(Sqlite, BindsAndReadsEveryType) {
  TempDir dir;
  Database db(dir.file("t.db"));
  db.exec("CREATE TABLE t (i INTEGER, d REAL, s TEXT, b BLOB, n INTEGER)");
  const Bytes blob = {0x00, 0xff, 0x10};
  db.prepare("INSERT INTO t VALUES (?, ?, ?, ?, ?)")
      .bind_all(std::int64_t{-9'000'000'000}, 2.5, std::string_view("héllo"),
                std::span<const std::uint8_t>(blob), std::optional<int>())
      .run();
  Statement st = db.prepare("SELECT i, d, s, b, n FROM t");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.column_int64(0), -9'000'000'000);
  EXPECT_DOUBLE_EQ(st.column_double(1), 2.5);
  EXPECT_EQ(st.column_text(2), "héllo");
  EXPECT_EQ(st.column_blob(3), blob);
  EXPECT_TRUE(st.column_is_null(4));
  EXPECT_EQ(st.column_opt_int64(4), std::nullopt);
  EXPECT_EQ(st.column_name(2), "s");
  EXPECT_FALSE(st.step());
}

TEST(Sqlite, EmptyBlobIsNotNull) {
  TempDir dir;
  Database db(dir.file("t.db"));
  db.exec("CREATE TABLE t (b BLOB NOT NULL)");
  db.prepare("INSERT INTO t VALUES (?)").bind(1, std::span<const std::uint8_t>()).run();
  EXPECT_EQ(db.query_int64("SELECT length(b) FROM t"), 0);
}

TEST(Sqlite, TransactionRollsBackUnlessCommitted) {
  TempDir dir;
  Database db(dir.file("t.db"));
  db.exec("CREATE TABLE t (x INTEGER)");
  {
    Transaction tx(db);
    db.exec("INSERT INTO t VALUES (1)");
  }
  EXPECT_EQ(db.query_int64("SELECT count(*) FROM t"), 0);
  {
    Transaction tx(db);
    db.exec("INSERT INTO t VALUES (1)");
    tx.commit();
  }
  EXPECT_EQ(db.query_int64("SELECT count(*) FROM t"), 1);
}

TEST(Sqlite, CachedStatementIsResetAfterUse) {
  TempDir dir;
  Database db(dir.file("t.db"));
  db.exec("CREATE TABLE t (x INTEGER); INSERT INTO t VALUES (1), (2), (3);");
  for (int round = 0; round < 3; ++round) {
    auto st = db.cached("SELECT x FROM t ORDER BY x");
    ASSERT_TRUE(st->step());
    EXPECT_EQ(st->column_int64(0), 1) << "round " << round;  // restarted, not continued
  }
}

TEST(Sqlite, ErrorsNameFileCodeAndSql) {
  TempDir dir;
  const std::string path = dir.file("t.db");
  Database db(path);
  try {
    db.prepare("SELECT * FROM no_such_table");
    FAIL() << "expected SqliteError";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.code(), SQLITE_ERROR);
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no_such_table"), std::string::npos) << e.what();
  }
  db.exec("CREATE TABLE u (x INTEGER UNIQUE); INSERT INTO u VALUES (1);");
  try {
    db.exec("INSERT INTO u VALUES (1)");
    FAIL() << "expected SqliteError";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.code(), SQLITE_CONSTRAINT);
    EXPECT_EQ(e.extended_code(), SQLITE_CONSTRAINT_UNIQUE);
  }
}

TEST(Sqlite, OpenFailureNamesPath) {
  try {
    Database db("/nonexistent-dir/x/y.db");
    FAIL() << "expected SqliteError";
  } catch (const SqliteError& e) {
    EXPECT_EQ(e.code(), SQLITE_CANTOPEN);
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x/y.db"), std::string::npos);
  }
}

}  // namespace
}  // namespace fleetgw::storage
