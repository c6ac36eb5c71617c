#include "gateway/tools/operator/watch_command.h"

#include <CLI/CLI.hpp>
#include <string>

namespace fleetgw::tools {

void add_watch_options(CLI::App& app, WatchOptions& o) {
  app.add_option("--broker", o.broker, "broker URI")->capture_default_str();
  app.add_option("--topic", o.topic, "topic filter")->capture_default_str();
  app.add_option("--ca-file", o.ca_file, "CA bundle (TLS)");
  app.add_option("--cert-file", o.cert_file, "client certificate (mutual TLS)");
  app.add_option("--key-file", o.key_file, "client key (mutual TLS)");
  app.add_option("--username", o.username, "user name");
  app.add_option("--password", o.password, "password");
  app.add_option("--count", o.max_messages, "stop after this many messages");
  app.add_option("--duration", o.duration_s, "stop after this many seconds");
}

}  // namespace fleetgw::tools
