// `fleetgw watch`: a subscriber that decodes every fleetgw.v1.Envelope published under a topic
// filter and prints one JSON object per message ({"topic", "envelope"}). It is what a backend
// developer or a technician uses to see what a bike sends; the demo uses it to show the path
// from the simulated bus to the broker.
//
// Contract: runs until SIGINT/SIGTERM or `max_messages`/`duration_s`; a payload that is not an
// Envelope is reported as {"topic", "error"} and the watch goes on. Retained status messages
// are shown too. Exit status 0, or 1 when the broker cannot be reached.
//
// It runs as its own program, fleetgw-watch (`fleetgw watch ...` execs it): JSON needs protobuf's
// reflection, and linking that into the service costs the IoT node about a megabyte of resident
// memory (docs/performance.md). The service binary never contains it.
#pragma once

#include <ostream>
#include <string>

namespace CLI {
class App;
}

namespace fleetgw::tools {

struct WatchOptions {
  std::string broker = "tcp://127.0.0.1:1883";
  std::string topic = "fleet/v1/#";
  std::string ca_file;  // TLS: CA bundle; cert/key for mutual TLS
  std::string cert_file;
  std::string key_file;
  std::string username;
  std::string password;
  long max_messages = 0;  // 0 = unlimited
  double duration_s = 0;  // 0 = until a signal
};

// The watch's command-line options, shared by `fleetgw watch --help` and fleetgw-watch.
void add_watch_options(CLI::App& app, WatchOptions& options);

int run_watch(const WatchOptions& options, std::ostream& out);

}  // namespace fleetgw::tools
