#include "gateway/app/watch_command.h"

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace fleetgw::app {

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

int exec_watch(int argc, char** argv) {
  std::vector<char*> args;
  std::string program = "fleetgw-watch";
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
  std::cerr << "fleetgw watch: cannot run " << program << " (not next to "
            << (ec ? std::string("fleetgw") : self.string()) << " nor on PATH)\n";
  return 127;
}

}  // namespace fleetgw::app
