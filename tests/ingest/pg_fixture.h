// Test support: a private PostgreSQL cluster for the ingest tests, in a temporary directory.
//
// Contract:
//  * postgres_bin_dir() finds Debian's server binaries (/usr/lib/postgresql/<v>/bin with initdb
//    and pg_ctl); empty when PostgreSQL is not installed (tests then skip).
//  * PostgresCluster runs initdb as the unprivileged user `postgres` (initdb refuses root) with
//    trust authentication for the superuser `fleet`, then starts the server on a Unix socket in
//    its directory only (no TCP listener), on a free port number; the constructor returns once
//    the server accepts connections (pg_ctl -w) or throws std::runtime_error quoting its log.
//  * conninfo() is a libpq connection string for database `postgres` as `fleet`.
//  * stop() shuts the server down (fast mode, waits); start() starts it again on the same socket
//    and port (an outage and its end, for retry tests).
//  * The destructor stops the server (immediate mode) and removes the directory; never throws.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "tests/support/temp_dir.h"

namespace fleetgw::testing {

std::filesystem::path postgres_bin_dir();

class PostgresCluster {
 public:
  PostgresCluster();
  ~PostgresCluster();
  PostgresCluster(const PostgresCluster&) = delete;
  PostgresCluster& operator=(const PostgresCluster&) = delete;

  std::string conninfo() const;
  std::string log() const;
  void stop();
  void start();

 private:
  TempDir dir_;
  std::filesystem::path bin_;
  std::filesystem::path data_;
  std::filesystem::path socket_dir_;
  std::uint16_t port_ = 0;
};

}  // namespace fleetgw::testing
