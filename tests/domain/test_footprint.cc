// Database footprint of one hour of riding at the default sampling rates: the simulated bike
// rides for an hour, the trackers write into a real Store (flushed every 200 ms like the
// gateway), and the file size is compared with the empty database. The figure is printed for the
// README and bounded so that a sampling regression fails the test.

#include <filesystem>
#include <iostream>

#include <gtest/gtest.h>

#include "domain_test_util.h"

namespace fleetgw::domain::testing {
namespace {

uint64_t db_bytes(storage::Store& store) {
  const storage::Stats s = store.stats();
  return s.live_bytes;
}

TEST(Footprint, DatabaseBytesPerHourOfRiding) {
  TempDir dir;
  const auto db = dir.file("fleetgw.db");
  sim::Scenario sc = bundled("ride");
  sc.ride.clear();
  // One hour: 12 blocks of 4.5 min riding + 30 s traffic light.
  for (int i = 0; i < 12; ++i) {
    sc.ride.push_back({.duration_s = 270, .speed_kmh = 20.0 + (i % 3), .assist = std::nullopt});
    sc.ride.push_back({.duration_s = 30, .speed_kmh = 0, .assist = std::nullopt});
  }
  Harness h(std::move(sc), DomainConfig{}, db);
  h.run_until_offset(1);
  const uint64_t before = db_bytes(*h.gateway()->store());
  h.run_until_offset(3601);
  const uint64_t after = db_bytes(*h.gateway()->store());
  const storage::Stats stats = h.gateway()->store()->stats();

  const uint64_t per_hour = after - before;
  std::cout << "[footprint] 1 h riding: " << per_hour << " bytes of database ("
            << h.out.telemetry.size() << " telemetry samples, " << h.out.packs.size()
            << " pack snapshots, " << h.out.rides.size() << " ride upserts); file "
            << stats.file_bytes << " B + WAL " << stats.wal_bytes << " B\n";
  ::testing::Test::RecordProperty("bytes_per_riding_hour", static_cast<int>(per_hour));
  EXPECT_NEAR(static_cast<double>(h.out.telemetry.size()), 3600, 10);
  EXPECT_EQ(h.out.packs.size(), 12u);  // at 3 s, then every 5 min
  // Telemetry rows + their outbox payloads dominate: roughly 100-300 bytes per sample.
  EXPECT_GT(per_hour, 3600u * 60u);
  EXPECT_LT(per_hour, 3600u * 400u);
}

}  // namespace
}  // namespace fleetgw::domain::testing
