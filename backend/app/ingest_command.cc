// Options of `fleetgw ingest` (ingest_command.h).
#include "backend/app/ingest_command.h"

#include <CLI/CLI.hpp>
#include <cctype>
#include <string>

namespace fleetgw::app {

void add_ingest_options(CLI::App& app, ingest::IngestOptions& o) {
  app.add_option("--broker", o.broker, "broker URI (tcp://, ssl://, mqtt://, mqtts://)")
      ->capture_default_str();
  app.add_option("--topic-prefix", o.topic_prefix, "topic prefix of the fleet")
      ->capture_default_str();
  app.add_option("--group", o.group,
                 "shared-subscription group: workers of one group share the messages")
      ->capture_default_str();
  app.add_option("--client-id", o.client_id,
                 "MQTT client id, the same across restarts (default: GROUP-HOSTNAME)");
  app.add_option("--pg", o.pg,
                 "libpq connection string, e.g. \"host=/run/postgresql dbname=fleet\" (passwords "
                 "belong in ~/.pgpass or PGPASSWORD, not here)")
      ->required();
  app.add_option("--sessions", o.sessions, "MQTT sessions of this worker (all in its one process)")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--inflight", o.inflight,
                 "unacknowledged messages the broker may send each session (MQTT 5 receive "
                 "maximum): a batch holds at most sessions x inflight messages")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--batch", o.batch_rows, "a batch closes at this many rows...")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--batch-delay-ms", o.batch_delay_ms, "...or this long after its first message")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  app.add_option("--partition-days-ahead", o.partition_days_ahead,
                 "daily telemetry partitions created ahead")
      ->check(CLI::Range(1, 366))
      ->capture_default_str();
  app.add_option("--retention-days", o.retention_days,
                 "drop telemetry partitions older than this many days (0: keep everything)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--session-expiry-s", o.session_expiry_s,
                 "how long the broker keeps this worker's queue while it is away")
      ->check(CLI::Range(60, 365 * 24 * 3600))
      ->capture_default_str();
  app.add_option("--ca-file", o.ca_file, "CA bundle (TLS)");
  app.add_option("--cert-file", o.cert_file, "client certificate (mutual TLS)");
  app.add_option("--key-file", o.key_file, "client key (mutual TLS)");
  app.add_option("--username", o.username, "MQTT user name");
  app.add_option("--password", o.password, "MQTT password (never logged)");
  app.add_option("--duration", o.duration_s, "stop after this many seconds (0: run until a signal)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--gaps", o.gaps,
               "print the sequence gaps (vehicle, store, missing range) and exit: 0 when none");
  app.add_flag("--leave", o.leave,
               "leave the group for good: with the stopped worker's --client-id, --group and "
               "--sessions, unsubscribe, commit what the broker still queued for it, then end its "
               "sessions on the broker and exit 0 (a running worker does the same on SIGUSR1)");
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  // A service's settings also come from the environment, FLEETGW_INGEST_<OPTION> (the packaged
  // unit reads them from /etc/fleetgw-ingest/ingest.env, which keeps the broker and database
  // passwords out of the command line, visible in ps); a command-line value wins. Not --duration
  // or --gaps: those are one-off runs, not a service's settings.
  for (const char* name :
       {"broker", "topic-prefix", "group", "client-id", "pg", "sessions", "inflight", "batch",
        "batch-delay-ms", "partition-days-ahead", "retention-days", "session-expiry-s", "ca-file",
        "cert-file", "key-file", "username", "password", "log-level"}) {
    std::string env = "FLEETGW_INGEST_";
    for (const char* c = name; *c != '\0'; ++c) {
      env += *c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(*c)));
    }
    app.get_option(std::string("--") + name)->envname(env);
  }
}

}  // namespace fleetgw::app
