// GpsdClient loads libgps at its first connect (a process with [gnss] off never maps it): the
// library the build recorded loads and is used, and a missing one is a clear error, not a crash.
#include "gateway/gnss/gpsd_client.h"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <string>

namespace fleetgw::gnss {
namespace {

// A local TCP port nothing listens on: bound, read back, released.
int closed_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    ADD_FAILURE() << "no local port";
  }
  ::close(fd);
  return ntohs(addr.sin_port);
}

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
  const std::string port = std::to_string(closed_port());
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
