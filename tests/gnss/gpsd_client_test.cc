// GpsdClient loads libgps at its first connect (a process with [gnss] off never maps it): the
// library the build recorded loads and is used, and a missing one is a clear error, not a crash.
#include "gateway/gnss/gpsd_client.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/support/process.h"

namespace fleetgw::gnss {
namespace {

bool mapped(std::string_view library) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line)) {
    if (line.find(library) != std::string::npos) return true;
  }
  return false;
}

TEST(GpsdClient, LoadsLibgpsOnlyWhenItFirstConnects) {
  ASSERT_FALSE(mapped(FLEETGW_LIBGPS_SONAME)) << "linked, not loaded on demand";
  const std::string port =
      std::to_string(fleetgw::testing::free_loopback_port());  // nothing listens
  GpsdClient client("127.0.0.1", port);
  EXPECT_FALSE(mapped(FLEETGW_LIBGPS_SONAME)) << "constructing a client loads nothing";
  const std::string error = client.connect();
  // libgps answered: the refusal is its text, naming the endpoint.
  EXPECT_EQ(error.rfind("connect to 127.0.0.1:" + port + ": ", 0), 0u) << error;
  EXPECT_TRUE(mapped(FLEETGW_LIBGPS_SONAME));
  EXPECT_FALSE(client.connected());
  std::vector<GnssReport> reports;
  EXPECT_EQ(client.read_available(Micros(0), reports), GpsdClient::ReadStatus::kClosed);
}

TEST(GpsdClient, AMissingLibgpsIsAnErrorNamingTheLibraryAndTheSection) {
  GpsdClient client("127.0.0.1", "2947", "libgps-not-installed.so.99");
  const std::string error = client.connect();
  EXPECT_NE(error.find("cannot load libgps-not-installed.so.99, needed for [gnss]: "),
            std::string::npos)
      << error;
  EXPECT_FALSE(client.connected());
  EXPECT_EQ(client.fd(), -1);
  // Asking again gives the same answer (nothing half-loaded is kept).
  EXPECT_EQ(client.connect(), error);
}

}  // namespace
}  // namespace fleetgw::gnss
