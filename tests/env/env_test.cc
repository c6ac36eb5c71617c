#include "env/env.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "tests/support/temp_dir.h"

namespace fleetgw {
namespace {

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(ManualEnv, ClocksStandStillUntilTheTestMovesThem) {
  ManualEnv env(std::chrono::microseconds(5'000'000));
  const auto s0 = env.steady_now();
  EXPECT_EQ(env.wall_now(), std::chrono::microseconds(5'000'000));
  EXPECT_EQ(env.steady_now(), s0);
  env.advance(std::chrono::milliseconds(250));
  EXPECT_EQ(env.wall_now(), std::chrono::microseconds(5'250'000));
  EXPECT_EQ(env.steady_now() - s0, std::chrono::milliseconds(250));
  env.advance(std::chrono::milliseconds(-10));  // time never runs back
  EXPECT_EQ(env.steady_now() - s0, std::chrono::milliseconds(250));
  env.set_wall(std::chrono::microseconds(1'000));  // an NTP step moves the wall clock alone
  EXPECT_EQ(env.wall_now(), std::chrono::microseconds(1'000));
  EXPECT_EQ(env.steady_now() - s0, std::chrono::milliseconds(250));
}

TEST(SystemEnv, WallClockIsTheUnixEpochClock) {
  const auto sys = std::chrono::duration_cast<std::chrono::microseconds>(
      std::chrono::system_clock::now().time_since_epoch());
  const auto env = Env::system().wall_now();
  EXPECT_LT(std::chrono::abs(env - sys), std::chrono::seconds(60));
}

TEST(SystemEnv, ThreadsStopAndJoinWhenTheirHandleGoes) {
  std::atomic<bool> stopped{false};
  {
    auto t = Env::system().start_thread("env-test-thread-long-name", [&](std::stop_token st) {
      while (!st.stop_requested()) std::this_thread::yield();
      stopped = true;
    });
  }
  EXPECT_TRUE(stopped.load());
}

TEST(SystemEnv, AtomicWriteReplacesTheFileAndLeavesNoTemporary) {
  testing::TempDir dir;
  const auto p = dir.path() / "bundle.bin";
  ASSERT_FALSE(Env::system().write_file_atomic(p, "first"));
  ASSERT_FALSE(Env::system().write_file_atomic(p, std::string("second\0x", 8)));
  EXPECT_EQ(read_all(p), std::string("second\0x", 8));
  EXPECT_FALSE(std::filesystem::exists(p.string() + ".tmp"));
  std::uint64_t free = 0;
  EXPECT_FALSE(Env::system().free_space(dir.path(), free));
  EXPECT_GT(free, 0u);
}

TEST(SystemEnv, FailuresAreErrorCodesNamingTheCause) {
  const std::filesystem::path missing = "/nonexistent-dir-fleetgw/x/y.bin";
  const auto ec = Env::system().write_file_atomic(missing, "x");
  EXPECT_EQ(ec, std::errc::no_such_file_or_directory);
  EXPECT_TRUE(Env::system().rename_file("/nonexistent-dir-fleetgw/a", "/tmp/b"));
}

}  // namespace
}  // namespace fleetgw
