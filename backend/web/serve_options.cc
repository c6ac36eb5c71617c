// Options of `fleetgw serve` (serve_command.h).
#include "backend/web/serve_command.h"

#include <CLI/CLI.hpp>
#include <cctype>

namespace fleetgw::web {

void add_serve_options(CLI::App& app, ServeOptions& o) {
  app.add_option("--pg", o.pg,
                 "libpq connection string of the ingest's database (passwords belong in "
                 "~/.pgpass or PGPASSWORD, not here)")
      ->required();
  app.add_option("--listen", o.listen, "HOST:PORT to serve on ([::1]:PORT for IPv6)")
      ->capture_default_str();
  app.add_option("--tls-cert", o.tls_cert, "PEM certificate (chain): serve HTTPS");
  app.add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert");
  app.add_flag("--insecure-http", o.insecure_http,
               "allow plain HTTP on a non-loopback address (only behind a proxy that "
               "terminates TLS)");
  app.add_option("--static-dir", o.static_dir, "the console's files (default: installed ones)");
  app.add_option("--leaflet-dir", o.leaflet_dir, "Leaflet's files (Debian's libjs-leaflet)")
      ->capture_default_str();
  app.add_option("--tile-url", o.tile_url,
                 "map tile URL template, e.g. https://tile.example.org/{z}/{x}/{y}.png "
                 "(none: a plain background)");
  app.add_option("--tile-attribution", o.tile_attribution, "text credited on the map");
  app.add_option("--threads", o.threads, "request threads (each live-update stream holds one)")
      ->check(CLI::Range(4, 1024))
      ->capture_default_str();
  app.add_option("--db-connections", o.db_connections, "PostgreSQL connections in the pool")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--max-event-streams", o.max_event_streams,
                 "concurrent live-update (/api/events) streams")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--poll-ms", o.poll_ms, "how often the database is polled for live updates")
      ->check(CLI::Range(100, 60000))
      ->capture_default_str();
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  app.add_option("--add-operator", o.add_operator,
                 "create or update the operator NAME (password: first line of stdin) and exit");
  app.add_option("--role", o.role, "role of --add-operator: viewer, operator or admin")
      ->check(CLI::IsMember({"viewer", "operator", "admin"}));
  app.add_option("--remove-operator", o.remove_operator, "delete the operator NAME and exit");
  // As for fleetgw-ingest: a service's settings also come from FLEETGW_SERVE_<OPTION> (the
  // unit's environment file keeps the database password out of ps); the command line wins.
  for (const char* name : {"pg", "listen", "tls-cert", "tls-key", "static-dir", "leaflet-dir",
                           "tile-url", "tile-attribution", "threads", "db-connections",
                           "max-event-streams", "poll-ms", "log-level"}) {
    std::string env = "FLEETGW_SERVE_";
    for (const char* c = name; *c != '\0'; ++c) {
      env += *c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(*c)));
    }
    app.get_option(std::string("--") + name)->envname(env);
  }
}

}  // namespace fleetgw::web
