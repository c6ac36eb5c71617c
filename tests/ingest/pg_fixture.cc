// Private PostgreSQL cluster for tests (pg_fixture.h).
#include "tests/ingest/pg_fixture.h"

#include <pwd.h>
#include <unistd.h>

#include <fstream>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "backend/common/pg.h"
#include "backend/ingest/migrations.h"
#include "tests/support/process.h"

namespace fleetgw::testing {
namespace fs = std::filesystem;

fs::path postgres_bin_dir() {
  std::error_code ec;
  fs::path best;
  for (const auto& entry : fs::directory_iterator("/usr/lib/postgresql", ec)) {
    const fs::path bin = entry.path() / "bin";
    if (fs::exists(bin / "initdb") && fs::exists(bin / "pg_ctl") && bin > best) best = bin;
  }
  return best;
}

namespace {

// Commands run as `postgres` when we are root (initdb refuses root), as ourselves otherwise.
std::vector<std::string> as_postgres(std::vector<std::string> argv) {
  if (::geteuid() != 0) return argv;
  argv.insert(argv.begin(), {"runuser", "-u", "postgres", "--"});
  return argv;
}

void give_to_postgres(const fs::path& p) {
  if (::geteuid() != 0) return;
  const passwd* pw = ::getpwnam("postgres");
  if (pw == nullptr) throw std::runtime_error("no user `postgres` to run the test cluster as");
  if (::chown(p.c_str(), pw->pw_uid, pw->pw_gid) != 0) {
    throw std::system_error(errno, std::generic_category(), "chown " + p.string());
  }
}

}  // namespace

PostgresCluster::PostgresCluster() : bin_(postgres_bin_dir()) {
  if (bin_.empty()) throw std::runtime_error("PostgreSQL server binaries not found");
  // The temporary directory must be traversable by `postgres`; what is inside is its own.
  fs::permissions(dir_.path(),
                  fs::perms::owner_all | fs::perms::group_exec | fs::perms::others_exec);
  data_ = dir_.path() / "data";
  socket_dir_ = dir_.path() / "sock";
  fs::create_directories(data_);
  fs::create_directories(socket_dir_);
  give_to_postgres(data_);
  give_to_postgres(socket_dir_);
  const fs::path out = dir_.path() / "setup.log";
  {
    // The log file is written by pg_ctl as `postgres`.
    std::ofstream touch(dir_.path() / "server.log");
  }
  give_to_postgres(dir_.path() / "server.log");
  run_program(as_postgres({(bin_ / "initdb").string(), "-D", data_.string(), "-A", "trust", "-U",
                           "fleet", "--no-sync", "-E", "UTF8", "--locale=C"}),
              out);
  port_ = free_loopback_port();
  start();
}

void PostgresCluster::start() {
  const fs::path out = dir_.path() / "setup.log";
  const std::string server_opts = "-k " + socket_dir_.string() + " -p " + std::to_string(port_) +
                                  " -c listen_addresses='' -c fsync=on";
  if (run_for_exit_code(
          as_postgres({(bin_ / "pg_ctl").string(), "-D", data_.string(), "-o", server_opts, "-l",
                       (dir_.path() / "server.log").string(), "-w", "-t", "60", "start"}),
          out) != 0) {
    throw std::runtime_error("PostgreSQL did not start:\n" + read_text_file(out) + log());
  }
}

void PostgresCluster::stop() {
  run_program(
      as_postgres({(bin_ / "pg_ctl").string(), "-D", data_.string(), "-m", "fast", "-w", "stop"}),
      dir_.path() / "setup.log");
}

PostgresCluster::~PostgresCluster() {
  try {
    run_for_exit_code(as_postgres({(bin_ / "pg_ctl").string(), "-D", data_.string(), "-m",
                                   "immediate", "-w", "stop"}),
                      dir_.path() / "setup.log");
  } catch (...) {
  }
}

std::string PostgresCluster::conninfo() const {
  return "host=" + socket_dir_.string() + " port=" + std::to_string(port_) +
         " user=fleet dbname=postgres";
}

std::string PostgresCluster::log() const {
  return read_text_file(dir_.path() / "server.log");
}

std::unique_ptr<PostgresCluster> PgDatabaseTest::cluster_;

void PgDatabaseTest::SetUpTestSuite() {
  if (postgres_bin_dir().empty()) return;
  cluster_ = std::make_unique<PostgresCluster>();
}

void PgDatabaseTest::TearDownTestSuite() {
  cluster_.reset();
}

void PgDatabaseTest::SetUp() {
  if (!cluster_) GTEST_SKIP() << "PostgreSQL server binaries not installed";
  PgConnection c(cluster_->conninfo());
  c.exec("DROP SCHEMA public CASCADE; CREATE SCHEMA public", "reset");
}

std::string PgDatabaseTest::text(const std::string& sql) {
  PgConnection c(cluster_->conninfo());
  const auto r = c.exec(sql, "query");
  return r.rows() == 0 || r.is_null(0, 0) ? "<null>" : r.str(0, 0);
}

std::int64_t PgDatabaseTest::int64(const std::string& sql) {
  PgConnection c(cluster_->conninfo());
  return c.exec(sql, "query").int64(0, 0);
}

void PgDatabaseTest::migrate_up_to(int version) {
  PgConnection c(cluster_->conninfo());
  c.exec(
      "CREATE TABLE schema_migrations (version integer PRIMARY KEY, name text NOT NULL, "
      "applied_at timestamptz NOT NULL DEFAULT now())",
      "schema_migrations");
  for (const auto& m : ingest::migrations()) {
    if (m.version > version) break;
    c.exec(m.sql, "old migration");
    c.exec("INSERT INTO schema_migrations (version, name) VALUES (" + std::to_string(m.version) +
               ", 'old')",
           "old migration's row");
  }
}

std::variant<ingest::Decoded, ingest::Reject> decode_as(const v1::Envelope& envelope,
                                                        std::string_view leaf) {
  return ingest::decode_message("fleet/v1",
                                "fleet/v1/" + envelope.vehicle_id() + "/" + std::string(leaf),
                                envelope.SerializeAsString());
}

ingest::Decoded decoded(const v1::Envelope& envelope, std::string_view leaf) {
  auto r = decode_as(envelope, leaf);
  if (auto* reject = std::get_if<ingest::Reject>(&r)) {
    throw std::runtime_error("the ingest refused the test's record: " + reject->code + ": " +
                             reject->detail);
  }
  return std::get<ingest::Decoded>(std::move(r));
}

}  // namespace fleetgw::testing
