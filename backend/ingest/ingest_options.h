// Options of `fleetgw ingest` (header only: the CLI of the fleetgw binary validates them without
// linking libpq; fleetgw-ingest runs them, see backend/app/ingest_command.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace fleetgw::ingest {

struct IngestOptions {
  std::string broker = "tcp://127.0.0.1:1883";
  std::string topic_prefix = "fleet/v1";
  std::string group = "fleetgw-ingest";
  // MQTT client id prefix; must stay the same across restarts of one worker so its persistent
  // sessions (and the messages the broker queued for them) are resumed: session i is
  // "<client_id>-s<i>". Default: "<group>-<hostname>".
  std::string client_id;
  std::string pg;  // libpq conninfo ("host=/run/postgresql dbname=fleet")
  // MQTT sessions of this worker (all in its one process and thread).
  std::size_t sessions = 4;
  // MQTT 5 receive maximum of each session: how many unacknowledged messages the broker may
  // send it. A batch holds at most sessions x inflight messages.
  std::uint32_t inflight = 3000;
  std::size_t batch_rows = 20000;     // a batch closes at this many rows...
  std::uint32_t batch_delay_ms = 50;  // ...or this long after its first message
  int partition_days_ahead = 7;       // telemetry partitions created ahead
  int retention_days = 0;             // telemetry partitions older than this dropped (0: never)
  std::uint32_t session_expiry_s = 7 * 24 * 3600;
  std::uint32_t max_packet_bytes = 1024 * 1024;
  std::string ca_file;
  std::string cert_file;
  std::string key_file;
  std::string username;
  std::string password;   // never logged
  double duration_s = 0;  // 0 = until SIGINT/SIGTERM
  bool gaps = false;      // print the gap report and exit
  // Leave the group for good: connect the sessions of client_id, unsubscribe, drain what the
  // broker still queued for them, then end them (session expiry 0) and exit.
  bool leave = false;
  std::string log_level = "info";
};

}  // namespace fleetgw::ingest
