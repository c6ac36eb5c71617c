// Test support for `fleetgw serve`: a private PostgreSQL cluster with the ingest's real schema
// (made by the real fleetgw-ingest), the real fleetgw-serve program on a free loopback port,
// HTTP helpers, and rows written into the ingest's tables as the ingest writes them.
//
// Contract:
//  * ServeStack starts once per test suite (SetUpTestSuite) and is shared by its tests, which
//    therefore use their own operators and vehicles. It throws std::runtime_error (with the
//    server's log) when something does not start; tests skip without PostgreSQL.
//  * login() returns the session cookie and CSRF token (empty on failure, with the status).
//  * insert_vehicle()/insert_alarm()/... write rows with the columns the ingest fills.
#pragma once

#include <httplib.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "backend/common/pg.h"
#include "tests/ingest/pg_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing {

struct LoginResult {
  int status = 0;
  std::string cookie;      // "fleet_session=..." as the browser sends it back
  std::string set_cookie;  // the whole Set-Cookie header
  std::string csrf;
  std::string retry_after;  // the Retry-After header of a 429
};

struct VehicleRow {
  std::string id;
  double lat = 0;
  double lon = 0;
  std::string mode = "VEHICLE_MODE_PARKED";
  std::optional<int> soc_pct = 80;
  std::optional<bool> status_online = true;  // nullopt: no status row
};

class ServeStack {
 public:
  // tls: a throw-away self-signed certificate for 127.0.0.1 (openssl CLI) and HTTPS; the
  // clients then trust exactly that certificate.
  explicit ServeStack(std::vector<std::string> extra_args = {}, bool tls = false);
  ~ServeStack();

  std::string url() const {
    return std::string(tls_ ? "https" : "http") + "://127.0.0.1:" + std::to_string(port_);
  }
  std::uint16_t port() const { return port_; }
  const std::string& conninfo() const { return conninfo_; }
  fleetgw::PgConnection& db() { return *db_; }
  std::string log() const { return serve_ ? serve_->log() : ""; }
  const std::filesystem::path& dir() const { return dir_.path(); }

  // `fleetgw serve --add-operator` with the password on stdin; returns its exit code.
  int add_operator(const std::string& name, const std::string& role, const std::string& password);

  httplib::Client client() const;
  LoginResult login(const std::string& name, const std::string& password) const;

  void insert_vehicle(const VehicleRow& v);
  void insert_alarm(const std::string& vehicle, std::int64_t sequence, const std::string& kind,
                    const std::string& transition, std::int64_t at_us,
                    const std::string& detail = "");
  void insert_sample(const std::string& vehicle, std::int64_t sequence, std::int64_t at_us,
                     int speed_dkmh, double lat, double lon);
  void insert_lock(const std::string& vehicle, std::int64_t sequence,
                   const std::string& state_name);

  // Rows of a query as text ("" for NULL), for assertions on the console's own tables.
  std::vector<std::vector<std::string>> rows(const std::string& sql,
                                             const std::vector<std::string>& params = {});

 private:
  TempDir dir_;
  std::unique_ptr<PostgresCluster> cluster_;
  std::string conninfo_;
  std::unique_ptr<fleetgw::PgConnection> db_;
  std::uint16_t port_ = 0;
  std::unique_ptr<ChildProcess> serve_;
  bool tls_ = false;
};

std::int64_t now_us();

}  // namespace fleetgw::testing
