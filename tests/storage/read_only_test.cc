// Inspection never modifies (`fleetgw db`): a read-only Store takes no lock, runs no migration,
// never creates, moves or renames a file, works while a writer holds the database, and says
// clearly when a file is not a fleetgw store. The writer refuses a missing directory.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;
namespace fs = std::filesystem;

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) {
    names.insert(e.path().filename().string() + ":" +
                 std::to_string(e.is_regular_file() ? fs::file_size(e.path()) : 0));
  }
  return names;
}

std::string not_a_store_message(const std::string& path) {
  try {
    Store store(StoreOptions{.path = path, .read_only = true});
  } catch (const NotAStoreError& e) {
    return e.what();
  }
  ADD_FAILURE() << path << " was opened as a store";
  return {};
}

TEST(ReadOnly, TextFileIsRefusedAndLeftExactlyAsItWas) {
  TempDir dir;
  const std::string path = dir.file("ride.log");
  {
    std::ofstream out(path);
    out << "(1700000000.000000) can0 710#55AA0C1010\n(1700000000.001000) can0 710#0102\n";
  }
  const auto before = listing(dir.path());
  const auto content = read_all(path);
  const std::string message = not_a_store_message(path);
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("not a fleetgw store"), std::string::npos) << message;
  EXPECT_EQ(listing(dir.path()), before) << "nothing created, moved or renamed";
  EXPECT_EQ(read_all(path), content);
}

TEST(ReadOnly, MissingFileIsRefusedAndNotCreated) {
  TempDir dir;
  const std::string path = dir.file("absent.db");
  const std::string message = not_a_store_message(path);
  EXPECT_NE(message.find("no database"), std::string::npos) << message;
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(ReadOnly, EmptyFileAndForeignSqliteDatabaseAreNotStores) {
  TempDir dir;
  const std::string empty = dir.file("empty.db");
  std::ofstream(empty).close();
  EXPECT_NE(not_a_store_message(empty).find("empty file"), std::string::npos);
  EXPECT_EQ(fs::file_size(empty), 0u);

  const std::string foreign = dir.file("other.sqlite");
  {
    Database raw(foreign);
    raw.exec("CREATE TABLE contacts (name TEXT)");
  }
  const auto before = listing(dir.path());
  EXPECT_NE(not_a_store_message(foreign).find("not a fleetgw store"), std::string::npos);
  EXPECT_EQ(listing(dir.path()), before);
}

TEST(ReadOnly, ReadsWhileTheWriterHoldsTheFileAndTouchesNothing) {
  TempDir dir;
  const std::string path = dir.file("live.db");
  Store writer(StoreOptions{.path = path});
  Batch b;
  for (int i = 0; i < 50; ++i) b.faults.push_back({fault_at(i, i), payload_of("f")});
  ASSERT_TRUE(writer.write(b).ok());
  const auto before = listing(dir.path());
  {
    Store reader(StoreOptions{.path = path, .read_only = true});
    EXPECT_TRUE(reader.read_only());
    std::uint64_t faults = 0;
    for (const auto& [table, rows] : reader.stats().table_rows) {
      if (table == "fault_events") faults = rows;
    }
    EXPECT_EQ(faults, 50u) << "sees what the writer committed (WAL)";
    // The writer is not blocked by the reader.
    Batch more;
    more.faults.push_back({fault_at(99, 99), payload_of("f")});
    EXPECT_TRUE(writer.write(more).ok());
    std::ostringstream rows;
    EXPECT_EQ(reader.export_table("fault_events", 0, rows), 51u);
    // And the reader cannot write.
    const auto r = reader.write(more);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code, StatusCode::kInvalid);
    EXPECT_EQ(reader.ack(std::vector<std::uint64_t>{1}).status().code, StatusCode::kInvalid);
  }
  // Same files (the WAL may have grown from the writer's second batch, nothing else).
  std::set<std::string> names_before, names_after;
  for (const auto& n : before) names_before.insert(n.substr(0, n.find(':')));
  for (const auto& n : listing(dir.path())) names_after.insert(n.substr(0, n.find(':')));
  EXPECT_EQ(names_after, names_before);
  EXPECT_FALSE(fs::exists(path + ".corrupt")) << "never moved aside";
}

TEST(ReadOnly, ClosedStoreIsReadWithoutCreatingSideFiles) {
  TempDir dir;
  const std::string path = dir.file("closed.db");
  {
    Store writer(StoreOptions{.path = path});
    Batch b;
    b.faults.push_back({fault_at(1, 1), payload_of("f")});
    ASSERT_TRUE(writer.write(b).ok());
  }
  fs::remove(path + ".lock");
  const auto before = listing(dir.path());
  {
    Store reader(StoreOptions{.path = path, .read_only = true});
    EXPECT_GE(reader.stats().next_seq, 2u);
  }
  EXPECT_EQ(listing(dir.path()), before) << "no lock file, no -wal/-shm left behind";
}

TEST(ReadOnly, WriterRefusesADirectoryThatDoesNotExist) {
  TempDir dir;
  const std::string path = (dir.path() / "no-such-dir" / "fleetgw.db").string();
  try {
    Store store(StoreOptions{.path = path});
    FAIL() << "opened a store in a missing directory";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("storage.path"), std::string::npos) << what;
    EXPECT_NE(what.find("no-such-dir"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(dir.path() / "no-such-dir")) << "never created";
}

}  // namespace
}  // namespace fleetgw::storage
