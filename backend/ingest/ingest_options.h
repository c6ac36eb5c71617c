// Options of `fleetgw ingest` (header only: the CLI of the fleetgw binary validates them without
// linking libpq; fleetgw-ingest runs them, see gateway/app/ingest_command.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace fleetgw::ingest {

struct IngestOptions {
  std::string broker = "tcp://127.0.0.1:1883";
  std::string topic_prefix = "fleet/v1";
  std::string group = "fleetgw-ingest";
  // MQTT client id; must stay the same across restarts of one worker so its persistent
  // session (and the messages the broker queued for it) is resumed. Default:
  // "<group>-<hostname>".
  std::string client_id;
  std::string pg;                // libpq conninfo ("host=/run/postgresql dbname=fleet")
  std::size_t batch_rows = 500;  // rows per INSERT statement (a telemetry batch is one message)
  std::uint32_t session_expiry_s = 7 * 24 * 3600;
  std::uint32_t max_packet_bytes = 1024 * 1024;
  std::string ca_file;
  std::string cert_file;
  std::string key_file;
  std::string username;
  std::string password;   // never logged
  double duration_s = 0;  // 0 = until SIGINT/SIGTERM
  bool gaps = false;      // print the gap report and exit
  std::string log_level = "info";
};

}  // namespace fleetgw::ingest
