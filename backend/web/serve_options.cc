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
  app.add_option("--broker", o.broker,
                 "MQTT broker for commands (tcp://, ssl://, mqtt://, mqtts://); none: the "
                 "console sends no commands");
  app.add_option("--topic-prefix", o.topic_prefix, "topic prefix of the fleet")
      ->capture_default_str();
  app.add_option("--ca-file", o.ca_file, "CA bundle (broker TLS)");
  app.add_option("--cert-file", o.cert_file, "client certificate (broker mutual TLS)");
  app.add_option("--key-file", o.key_file, "client key of --cert-file");
  app.add_option("--username", o.username, "MQTT user name");
  app.add_option("--password", o.password, "MQTT password (never logged)");
  app.add_option("--signing-key", o.signing_key,
                 "this server's Ed25519 private key (PEM, as fleetgw keygen writes it; refused "
                 "when its group or others may read it)");
  app.add_option("--delegation", o.delegation,
                 "the fleet root's delegation of --signing-key (a serialized "
                 "fleetgw.v1.SignedDelegation, fleetgw keys delegate)");
  app.add_option("--key-id", o.key_id,
                 "key id of --signing-key without --delegation (default: the file's stem)");
  app.add_option("--command-ttl-s", o.command_ttl_s,
                 "a command expires this long after it is signed")
      ->check(CLI::Range(5, 3600))
      ->capture_default_str();
  app.add_option("--root-key", o.root_keys,
                 "a fleet root's public key, ID=BASE64 or ID=FILE.pub (fleetgw keys root); "
                 "repeatable: revocation lists uploaded by an admin must be signed by one");
  app.add_option("--max-body-kib", o.max_body_bytes,
                 "largest request body in KiB (a zone upload's GeoJSON is one)")
      ->transform(
          [](std::string v) {
            long kib = 0;
            try {
              kib = std::stol(v);
            } catch (const std::exception&) {
              kib = 0;
            }
            if (kib < 16 || kib > 65536) {
              throw CLI::ValidationError("a whole number of KiB, 16..65536");
            }
            return std::to_string(kib * 1024);
          },
          "KiB")
      ->default_str("64");
  add_standards_options(app, o.standards);
  app.add_option("--add-operator", o.add_operator,
                 "create or update the operator NAME (password: first line of stdin) and exit");
  app.add_option("--role", o.role, "role of --add-operator: viewer, operator or admin")
      ->check(CLI::IsMember({"viewer", "operator", "admin"}));
  app.add_option("--remove-operator", o.remove_operator, "delete the operator NAME and exit");
  // As for fleetgw-ingest: a service's settings also come from FLEETGW_SERVE_<OPTION> (the
  // unit's environment file keeps the database password out of ps); the command line wins.
  for (const char* name : {"pg",
                           "listen",
                           "tls-cert",
                           "tls-key",
                           "static-dir",
                           "leaflet-dir",
                           "tile-url",
                           "tile-attribution",
                           "threads",
                           "db-connections",
                           "max-event-streams",
                           "poll-ms",
                           "log-level",
                           "broker",
                           "topic-prefix",
                           "ca-file",
                           "cert-file",
                           "key-file",
                           "username",
                           "password",
                           "signing-key",
                           "delegation",
                           "key-id",
                           "command-ttl-s"}) {
    std::string env = "FLEETGW_SERVE_";
    for (const char* c = name; *c != '\0'; ++c) {
      env += *c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(*c)));
    }
    app.get_option(std::string("--") + name)->envname(env);
  }
  app.get_option("--max-body-kib")->envname("FLEETGW_SERVE_MAX_BODY_KIB");
}

}  // namespace fleetgw::web
