// fleetgw-ingest: `fleetgw ingest` as its own program (see ingest_command.h for why).
#include <CLI/CLI.hpp>

#include <iostream>

#include "gateway/app/ingest_command.h"
#include "gateway/app/logging.h"
#include "gateway/app/protobuf_log.h"
#include "gateway/ingest/ingest_worker.h"

int main(int argc, char** argv) {
  CLI::App app{"fleetgw ingest: MQTT 5 shared subscription → PostgreSQL (docs/backend.md)"};
  fleetgw::ingest::IngestOptions options;
  fleetgw::app::add_ingest_options(app, options);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  fleetgw::app::setup_logging(options.log_level);
  // Hostile payloads must not write one stderr line each through protobuf (issue 11).
  const fleetgw::app::ProtobufLogRoute protobuf_log;
  try {
    return fleetgw::ingest::run_ingest(options);
  } catch (const std::exception& e) {
    std::cerr << "fleetgw ingest: " << e.what() << '\n';
    return 1;
  }
}
