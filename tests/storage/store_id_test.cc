// The store id (issue 15): a random UUID created with the store and kept in `meta`, so the
// backend's key (vehicle_id, store_id, sequence) tells a wiped store's records from the old ones.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <regex>
#include <string>

#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

const std::regex kUuidV4("[0-9a-f]{8}-[0-9a-f]{4}-4[0-9a-f]{3}-[89ab][0-9a-f]{3}-[0-9a-f]{12}");

TEST(StoreId, CreatedWithTheStoreKeptAcrossOpensNewForANewStore) {
  TempDir dir;
  const std::string path = dir.file("s.db");
  std::string first;
  {
    Store store(StoreOptions{.path = path});
    first = store.store_id();
    EXPECT_TRUE(std::regex_match(first, kUuidV4)) << first;
    EXPECT_EQ(store.meta("storage.store_id"), first);
  }
  {
    Store again(StoreOptions{.path = path});
    EXPECT_EQ(again.store_id(), first) << "a restart keeps the id";
  }
  {
    Store reader(StoreOptions{.path = path, .read_only = true});
    EXPECT_EQ(reader.store_id(), first);
  }
  std::filesystem::remove(path);
  std::filesystem::remove(path + "-wal");
  std::filesystem::remove(path + "-shm");
  Store wiped(StoreOptions{.path = path});
  EXPECT_TRUE(std::regex_match(wiped.store_id(), kUuidV4));
  EXPECT_NE(wiped.store_id(), first) << "a wiped store is a new store";
  EXPECT_EQ(wiped.next_seq(), 1u);
  Store other(StoreOptions{.path = dir.file("other.db")});
  EXPECT_NE(other.store_id(), wiped.store_id());
}

TEST(StoreId, AStoreWithoutOneGetsOneAtItsNextOpenAndKeepsItsSequence) {
  TempDir dir;
  const std::string path = dir.file("old.db");
  std::uint64_t next = 0;
  {
    Store store(StoreOptions{.path = path});
    Batch b;
    b.now_us = 1;
    b.messages.push_back(UplinkMessage{OutboxKind::kInfo, kLowestPriority, Bytes{1, 2, 3}});
    ASSERT_TRUE(store.write(b).ok());
    next = store.next_seq();
  }
  // A store written before v1.1 has no id.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "DELETE FROM meta WHERE key = 'storage.store_id'", nullptr, nullptr,
                         nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  {
    Store reader(StoreOptions{.path = path, .read_only = true});
    EXPECT_EQ(reader.store_id(), "") << "inspection never writes";
  }
  Store store(StoreOptions{.path = path});
  EXPECT_TRUE(std::regex_match(store.store_id(), kUuidV4));
  EXPECT_EQ(store.next_seq(), next);
}

}  // namespace
}  // namespace fleetgw::storage
