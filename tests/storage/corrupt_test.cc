// Start-up checks: a file that is not SQLite, or whose pages are damaged, is moved aside with
// its -wal/-shm to "<name>.corrupt-<timestamp>" and a fresh database is started; the bad file is
// never overwritten.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "env/env.h"
#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

void write_all(const std::string& path, const std::string& data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << data;
}

// 2023-11-14T22:13:20Z
constexpr std::int64_t kFixedClockUs = 1'700'000'000'000'000;

// The corrupt file is named from the store's Env (a ManualEnv standing still at kFixedClockUs):
// the names asserted below would carry today's date if the store read the real clock.
struct FixedClock {
  ManualEnv env{std::chrono::microseconds(kFixedClockUs)};
  StoreOptions options(const std::string& path) { return StoreOptions{.path = path, .env = &env}; }
};

void expect_fresh_and_usable(Store& store) {
  EXPECT_EQ(store.integrity_check(), "ok");
  EXPECT_EQ(store.next_seq(), 1u);
  Batch b;
  b.telemetry.push_back({telemetry_at(1), payload_of("x")});
  const auto written = store.write(b);
  ASSERT_TRUE(written.ok()) << written.status().message;
  EXPECT_EQ(written->first_seq, 1u);
}

TEST(Corrupt, GarbageFileIsMovedAsideNotOverwritten) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  const std::string garbage(8192, '\x5a');
  write_all(path, garbage);
  write_all(path + "-wal", "stale wal");
  FixedClock clock;
  Store store(clock.options(path));
  const std::string aside = path + ".corrupt-20231114T221320Z";
  ASSERT_EQ(store.moved_aside_path(), aside);
  EXPECT_EQ(read_all(aside), garbage) << "the bad file is kept byte for byte";
  EXPECT_EQ(read_all(aside + "-wal"), "stale wal") << "its WAL travels with it";
  expect_fresh_and_usable(store);
}

TEST(Corrupt, ShortFileIsMovedAside) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  write_all(path, "SQLite");
  FixedClock clock;
  Store store(clock.options(path));
  EXPECT_TRUE(store.moved_aside_path().has_value());
  expect_fresh_and_usable(store);
}

TEST(Corrupt, DamagedPagesFailQuickCheckAndAreMovedAside) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  {
    Store store(StoreOptions{.path = path});
    for (int n = 0; n < 20; ++n) {
      Batch b;
      for (int i = 0; i < 200; ++i) b.telemetry.push_back({telemetry_at(i), Bytes(50, 7)});
      store.write(b);
    }
  }  // closing checkpoints the WAL into the main file
  std::string bytes = read_all(path);
  ASSERT_GT(bytes.size(), 64u * 4096u);
  // Keep the header valid; smash b-tree pages in the middle of the file.
  for (std::size_t off = 16 * 4096; off < 40 * 4096; ++off)
    bytes[off] = static_cast<char>(off * 31);
  write_all(path, bytes);

  FixedClock clock;
  Store store(clock.options(path));
  ASSERT_TRUE(store.moved_aside_path().has_value());
  EXPECT_EQ(read_all(*store.moved_aside_path()), bytes);
  expect_fresh_and_usable(store);
}

TEST(Corrupt, SameSecondDoesNotClobberEarlierCopy) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  write_all(path, std::string(4096, 'a'));
  {
    FixedClock clock;
    Store store(clock.options(path));
  }
  std::filesystem::remove(path);
  std::filesystem::remove(path + "-wal");
  std::filesystem::remove(path + "-shm");
  write_all(path, std::string(4096, 'b'));
  FixedClock clock;
  Store store(clock.options(path));
  const std::string first = path + ".corrupt-20231114T221320Z";
  EXPECT_EQ(store.moved_aside_path(), first + "-1");
  EXPECT_EQ(read_all(first), std::string(4096, 'a'));
  EXPECT_EQ(read_all(first + "-1"), std::string(4096, 'b'));
}

TEST(Corrupt, HealthyDatabaseIsLeftAlone) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  {
    Store store(StoreOptions{.path = path});
    Batch b;
    b.faults.push_back({fault_at(1, 2), payload_of("f")});
    store.write(b);
  }
  Store store(StoreOptions{.path = path});
  EXPECT_FALSE(store.moved_aside_path().has_value());
  EXPECT_EQ(store.next_seq(), 2u);
}

TEST(Corrupt, EmptyFileIsANewDatabase) {
  TempDir dir;
  const std::string path = dir.file("bike.db");
  write_all(path, "");
  Store store(StoreOptions{.path = path});
  EXPECT_FALSE(store.moved_aside_path().has_value());
  EXPECT_EQ(store.integrity_check(), "ok");
}

}  // namespace
}  // namespace fleetgw::storage
