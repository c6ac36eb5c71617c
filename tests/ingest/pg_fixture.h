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
//  * PgDatabaseTest, the fixture of a gtest suite on a private cluster: the cluster starts once
//    for the suite (SetUpTestSuite; not at all when PostgreSQL is not installed, and then every
//    test of the suite is skipped) and stops after it; each test starts from an empty database
//    (the public schema dropped and made again: nothing the migrations made is left). A derived
//    SetUp() calls PgDatabaseTest::SetUp() first and returns if IsSkipped().
//  * text(sql) is the first column of the first row of `sql` as text ("<null>" for NULL or no
//    row), int64(sql) the same as an integer (PgError when it is not one).
//  * migrate_up_to(version): the database an older ingest left behind: schema_migrations and
//    the migrations up to `version`, each recorded as applied (for the upgrade tests).
//  * decode_as(envelope, leaf) is `envelope` as the ingest decodes it when it arrives on
//    fleet/v1/<its vehicle_id>/<leaf>; decoded() the same when the test knows it is accepted.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <variant>

#include "backend/ingest/envelope_rows.h"
#include "fleetgw/v1/envelope.pb.h"
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

class PgDatabaseTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite();
  static void TearDownTestSuite();
  void SetUp() override;

  static PostgresCluster& cluster() { return *cluster_; }
  static std::string conninfo() { return cluster_->conninfo(); }
  static std::string text(const std::string& sql);
  static std::int64_t int64(const std::string& sql);
  static void migrate_up_to(int version);

 private:
  // gtest's per-suite state: one suite runs at a time in a test binary.
  static std::unique_ptr<PostgresCluster> cluster_;
};

std::variant<ingest::Decoded, ingest::Reject> decode_as(const v1::Envelope& envelope,
                                                        std::string_view leaf);
ingest::Decoded decoded(const v1::Envelope& envelope, std::string_view leaf);

}  // namespace fleetgw::testing
