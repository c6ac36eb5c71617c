// fleetgw-serve: `fleetgw serve`, the backend's web server (http_server.h), as its own program
// beside fleetgw-ingest: it links libpq, OpenSSL's server side and libsodium, none of which the
// service binary on the IoT node loads. `fleetgw serve ...` execs it.
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <string>
#include <thread>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/console_schema.h"
#include "backend/web/http_server.h"
#include "backend/web/serve_command.h"

namespace {

namespace fs = std::filesystem;
using fleetgw::web::ServeOptions;

// The console's files: installed beside the program (../share/fleetgw/console), else the
// source tree this binary was built from (a build tree).
std::string default_static_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share/fleetgw/console";
    if (fs::is_regular_file(installed / "index.html", ec)) return installed.string();
  }
  return FLEETGW_WEB_SOURCE_STATIC_DIR;
}

int administer(const ServeOptions& o) {
  fleetgw::PgPool pool(o.pg, 1);
  {
    auto c = pool.lease();
    fleetgw::web::migrate_console_schema(*c);
  }
  fleetgw::web::Auth auth(pool);
  if (!o.remove_operator.empty()) {
    if (!auth.remove_operator(o.remove_operator)) {
      std::cerr << "fleetgw serve: no operator " << o.remove_operator << '\n';
      return 1;
    }
    auth.audit(std::nullopt, "local", "operator_remove", o.remove_operator, "ok");
    std::cout << "removed operator " << o.remove_operator << '\n';
    return 0;
  }
  const std::optional<fleetgw::web::Role> role = fleetgw::web::parse_role(o.role);
  if (!role) {
    std::cerr << "fleetgw serve: --add-operator needs --role viewer|operator|admin\n";
    return 2;
  }
  if (::isatty(STDIN_FILENO) != 0) std::cerr << "password for " << o.add_operator << ": ";
  std::string password;
  std::getline(std::cin, password);
  if (!password.empty() && password.back() == '\r') password.pop_back();
  try {
    auth.add_operator(o.add_operator, *role, password);
  } catch (const std::invalid_argument& e) {
    std::cerr << "fleetgw serve: --add-operator " << o.add_operator << ": " << e.what() << '\n';
    return 2;
  }
  auth.audit(std::nullopt, "local", "operator_add", o.add_operator, "ok", o.role);
  std::cout << "operator " << o.add_operator << " (" << o.role << ") saved\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "fleetgw serve: the operator console and API over the ingest's PostgreSQL "
      "(docs/console.md)"};
  ServeOptions o;
  fleetgw::web::add_serve_options(app, o);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("serve"));
  spdlog::set_level(spdlog::level::from_str(o.log_level));
  if (o.static_dir.empty()) o.static_dir = default_static_dir();

  try {
    // The vehicle registry, MDS agencies and zone bundles (issue 27), like --add-operator.
    if (o.standards.admin_requested()) {
      return fleetgw::web::run_standards_admin(o.pg, o.standards);
    }
    if (!o.add_operator.empty() || !o.remove_operator.empty()) return administer(o);

    // SIGINT/SIGTERM are taken with sigwait below; blocked before any thread starts, so every
    // thread inherits the mask and no handler runs anywhere.
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
    {
      fleetgw::PgConnection c(o.pg);
      const int applied = fleetgw::web::migrate_console_schema(c);
      if (applied > 0) spdlog::info("serve: applied {} console schema migration(s)", applied);
    }
    fleetgw::web::WebServer server(o);
    std::thread serving([&server] { server.run(); });
    spdlog::info("serve: listening on {} port {} ({}), console from {}", o.listen, server.port(),
                 o.tls_cert.empty() ? "HTTP" : "HTTPS", o.static_dir);
    int sig = 0;
    sigwait(&stop_signals, &sig);
    spdlog::info("serve: signal {}, stopping", sig);
    server.stop();
    serving.join();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "fleetgw serve: " << e.what() << '\n';
    return 1;
  }
}
