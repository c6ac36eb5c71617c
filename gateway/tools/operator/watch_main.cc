// fleetgw-watch: `fleetgw watch` as its own program (see watch_command.h for why).
#include <CLI/CLI.hpp>

#include <iostream>

#include "gateway/tools/operator/watch_command.h"

int main(int argc, char** argv) {
  CLI::App app{"fleetgw watch: print the Envelopes a broker receives, as JSON lines"};
  fleetgw::tools::WatchOptions options;
  fleetgw::tools::add_watch_options(app, options);
  CLI11_PARSE(app, argc, argv);
  try {
    return fleetgw::tools::run_watch(options, std::cout);
  } catch (const std::exception& e) {
    std::cerr << "fleetgw watch: " << e.what() << '\n';
    return 1;
  }
}
