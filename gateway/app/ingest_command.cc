// Options of `fleetgw ingest` and the exec of the sibling program (ingest_command.h).
#include "gateway/app/ingest_command.h"

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

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
  app.add_option("--batch", o.batch_rows, "rows per INSERT statement")
      ->check(CLI::Range(1, 2000))
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
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
}

int exec_sibling(std::string_view program_name, std::string_view command, int argc, char** argv) {
  std::string program(program_name);
  std::vector<char*> args;
  args.push_back(program.data());
  for (int i = 0; i < argc; ++i) args.push_back(argv[i]);
  args.push_back(nullptr);
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::string sibling = (self.parent_path() / program).string();
    ::execv(sibling.c_str(), args.data());
  }
  ::execvp(program.c_str(), args.data());
  std::cerr << "fleetgw " << command << ": cannot run " << program << " (not next to "
            << (ec ? std::string("fleetgw") : self.string()) << " nor on PATH)\n";
  return 127;
}

}  // namespace fleetgw::app
