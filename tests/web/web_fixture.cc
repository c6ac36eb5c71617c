// The stack behind the web server tests (web_fixture.h).
#include "tests/web/web_fixture.h"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "tests/support/wait.h"

namespace fleetgw::testing {

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

ServeStack::ServeStack(std::vector<std::string> extra_args, bool tls)
    : dir_("fleetgw-web"), tls_(tls) {
  cluster_ = std::make_unique<PostgresCluster>();
  conninfo_ = cluster_->conninfo();
  // The ingest's schema exactly as the ingest creates it: its first run applies the migrations
  // (--gaps then reports and exits).
  const int rc = run_for_exit_code({FLEETGW_INGEST_BINARY, "--gaps", "--pg", conninfo_},
                                   dir_ / "ingest-schema.log");
  if (rc != 0) {
    throw std::runtime_error("fleetgw-ingest --gaps failed: " +
                             read_text_file(dir_ / "ingest-schema.log"));
  }
  db_ = std::make_unique<fleetgw::PgConnection>(conninfo_);
  port_ = free_loopback_port();
  std::vector<std::string> argv = {
      FLEETGW_SERVE_BINARY, "--pg", conninfo_, "--listen", "127.0.0.1:" + std::to_string(port_),
      "--poll-ms",          "200"};
  argv.insert(argv.end(), extra_args.begin(), extra_args.end());
  if (tls_) {
    run_program(
        {"openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
         "-nodes", "-keyout", (dir_ / "key.pem").string(), "-out", (dir_ / "cert.pem").string(),
         "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"},
        dir_ / "openssl.log");
    argv.insert(argv.end(), {"--tls-cert", (dir_ / "cert.pem").string(), "--tls-key",
                             (dir_ / "key.pem").string()});
  }
  serve_ = std::make_unique<ChildProcess>(argv, dir_ / "serve.log");
  const bool up = wait_until(
      [&] {
        if (!serve_->running()) return true;
        auto res = client().Get("/api/health");
        return res && res->status == 200;
      },
      std::chrono::seconds(30), std::chrono::milliseconds(50));
  if (!up || !serve_->running()) throw std::runtime_error("fleetgw-serve did not start:\n" + log());
}

ServeStack::~ServeStack() {
  // A clean exit on SIGTERM is part of the contract (and where a sanitizer reports leaks).
  if (serve_ && serve_->running()) {
    const int rc = serve_->stop(std::chrono::seconds(10));
    if (rc != 0) ADD_FAILURE() << "fleetgw-serve exited " << rc << " on SIGTERM:\n" << log();
  }
}

int ServeStack::add_operator(const std::string& name, const std::string& role,
                             const std::string& password) {
  const auto input = dir_ / ("password-" + name);
  std::ofstream(input) << password << '\n';
  // ChildProcess reads stdin from /dev/null: a shell feeds the file instead (arguments quoted
  // by position, never spliced).
  return run_for_exit_code(
      {"sh", "-c", "exec \"$0\" --pg \"$1\" --add-operator \"$2\" --role \"$3\" < \"$4\"",
       FLEETGW_SERVE_BINARY, conninfo_, name, role, input.string()},
      dir_ / "admin.log");
}

httplib::Client ServeStack::client() const {
  httplib::Client c(url());
  if (tls_) c.set_ca_cert_path((dir_ / "cert.pem").string());
  c.set_connection_timeout(5, 0);
  c.set_read_timeout(20, 0);
  return c;
}

LoginResult ServeStack::login(const std::string& name, const std::string& password) const {
  LoginResult out;
  const nlohmann::json body = {{"name", name}, {"password", password}};
  auto res = client().Post("/api/login", body.dump(), "application/json");
  if (!res) return out;
  out.status = res->status;
  out.retry_after = res->get_header_value("Retry-After");
  if (res->status != 200) return out;
  out.set_cookie = res->get_header_value("Set-Cookie");
  out.cookie = out.set_cookie.substr(0, out.set_cookie.find(';'));
  out.csrf = nlohmann::json::parse(res->body).value("csrf_token", "");
  return out;
}

void ServeStack::insert_vehicle(const VehicleRow& v) {
  const auto e7 = [](double deg) { return std::to_string(static_cast<long long>(deg * 1e7)); };
  const fleetgw::PgParam s[] = {
      v.id,      std::to_string(now_us()),
      v.mode,    v.soc_pct ? fleetgw::PgParam(std::to_string(*v.soc_pct)) : std::nullopt,
      e7(v.lat), e7(v.lon)};
  db_->query(
      "INSERT INTO vehicle_state (vehicle_id, updated_at_us, online, mode, soc_pct, range_m, "
      "lat_e7, lon_e7) VALUES ($1, $2, true, $3, $4, 20000, $5, $6)",
      s, "vehicle_state row");
  if (v.status_online) {
    const fleetgw::PgParam st[] = {
        v.id, std::to_string(now_us()),
        *v.status_online ? "ONLINE_STATE_ONLINE" : "ONLINE_STATE_OFFLINE"};
    db_->query(
        "INSERT INTO status (vehicle_id, created_at_us, online, connection, outbox_depth, "
        "bus_state, firmware_version, last_will, attention) VALUES ($1, $2, $3, "
        "'CONNECTION_STATE_CONNECTED', 0, 'BUS_STATE_ACTIVE', '0.1.0', false, '{}')",
        st, "status row");
  }
}

void ServeStack::insert_alarm(const std::string& vehicle, std::int64_t sequence,
                              const std::string& kind, const std::string& transition,
                              std::int64_t at_us, const std::string& detail) {
  const fleetgw::PgParam p[] = {
      vehicle, std::to_string(sequence), std::to_string(at_us), kind, transition, detail};
  db_->query(
      "INSERT INTO alarms (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
      "kind, transition, at_us, lock_kind, detail) VALUES ($1, 'store-1', $2, $3, '0.1.0', $4, "
      "$5, $3, '', $6)",
      p, "alarm row");
}

void ServeStack::insert_sample(const std::string& vehicle, std::int64_t sequence,
                               std::int64_t at_us, int speed_dkmh, double lat, double lon) {
  const fleetgw::PgParam p[] = {vehicle,
                                std::to_string(sequence),
                                std::to_string(at_us),
                                std::to_string(speed_dkmh),
                                std::to_string(static_cast<long long>(lat * 1e7)),
                                std::to_string(static_cast<long long>(lon * 1e7))};
  db_->query(
      "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
      "sampled_at_us, speed_dkmh, lat_e7, lon_e7) VALUES ($1, 'store-1', $2, $3, $3, $4, $5, "
      "$6)",
      p, "telemetry row");
}

void ServeStack::insert_lock(const std::string& vehicle, std::int64_t sequence,
                             const std::string& state_name) {
  const fleetgw::PgParam p[] = {vehicle, std::to_string(sequence), std::to_string(now_us()),
                                state_name};
  db_->query(
      "INSERT INTO lock_events (vehicle_id, store_id, sequence, created_at_us, "
      "gateway_fw_version, node, lock_kind, previous_state, state, previous_state_name, "
      "state_name, source, at_us, command_id) VALUES ($1, 'store-1', $2, $3, '0.1.0', 'U21', "
      "'frame', 'LOCK_STATE_UNLOCKED', 'LOCK_STATE_LOCKED', 'open', $4, "
      "'LOCK_EVENT_SOURCE_COMMAND', $3, '')",
      p, "lock row");
}

std::vector<std::vector<std::string>> ServeStack::rows(const std::string& sql,
                                                       const std::vector<std::string>& params) {
  std::vector<fleetgw::PgParam> p(params.begin(), params.end());
  const fleetgw::PgResult r = db_->query(sql, p, "test query");
  std::vector<std::vector<std::string>> out;
  for (int i = 0; i < r.rows(); ++i) {
    std::vector<std::string> row;
    for (int c = 0; c < r.cols(); ++c) row.push_back(r.str(i, c));
    out.push_back(std::move(row));
  }
  return out;
}

}  // namespace fleetgw::testing
