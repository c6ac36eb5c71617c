// Options of `fleetgw serve` (fleetgw-serve), shared by the CLI front end and the program.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "backend/web/registry_options.h"

namespace fleetgw::web {

struct ServeOptions {
  std::string pg;                         // libpq connection string
  std::string listen = "127.0.0.1:8080";  // HOST:PORT ([::1]:PORT for IPv6)
  std::string tls_cert;                   // PEM certificate chain; with tls_key: HTTPS
  std::string tls_key;
  bool insecure_http = false;  // plain HTTP on a non-loopback address (behind a TLS proxy)
  std::string static_dir;      // the console's files (default: installed or source tree)
  std::string leaflet_dir = "/usr/share/javascript/leaflet";
  std::string tile_url;  // e.g. https://tile.example.org/{z}/{x}/{y}.png ("": no tiles)
  std::string tile_attribution;
  int threads = 32;            // request threads (each SSE stream holds one)
  int db_connections = 8;      // pool size
  int max_event_streams = 16;  // concurrent /api/events streams per instance
  int poll_ms = 1000;          // change poll interval (live updates)
  std::size_t max_body_bytes = 64 * 1024;
  std::string log_level = "info";
  // Commands (issue 28): the broker, this server's signing key and the root's delegation of it.
  std::string broker;  // "" = commands off (the API answers 503)
  std::string topic_prefix = "fleet/v1";
  std::string ca_file;  // TLS to the broker, as for fleetgw ingest
  std::string cert_file;
  std::string key_file;
  std::string username;
  std::string password;     // never logged
  std::string signing_key;  // PKCS#8 PEM Ed25519 private key (mode 0600)
  std::string delegation;   // serialized fleetgw.v1.SignedDelegation ("": a plain trusted key)
  std::string key_id;       // without a delegation: the key id (default: the key file's stem)
  int command_ttl_s = 60;   // a command's validity: expires_at = issued_at + this
  // The fleet's root public keys ("ID=BASE64" or "ID=FILE.pub", as `fleetgw keys root` prints
  // and writes them): revocation lists uploaded by an admin must be signed by one of them.
  std::vector<std::string> root_keys;
  StandardsOptions standards;  // GBFS, MDS and the vehicle registry (issue 27)
  // One-off administration instead of serving:
  std::string add_operator;  // with role; the password is read from stdin
  std::string role;
  std::string remove_operator;
};

}  // namespace fleetgw::web
