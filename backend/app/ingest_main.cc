// fleetgw-ingest: `fleetgw ingest` as its own program (see ingest_command.h for why).
#include <google/protobuf/stubs/common.h>
#include <google/protobuf/stubs/logging.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "backend/app/ingest_command.h"
#include "backend/ingest/ingest_worker.h"

namespace {

// Protobuf prints a stderr line for each invalid UTF-8 string it meets: hostile payloads must
// not write one line each (issue 11). Decode failures are counted and logged by the worker.
void quiet_protobuf(google::protobuf::LogLevel level, const char*, int, const std::string& m) {
  if (level == google::protobuf::LOGLEVEL_FATAL) spdlog::critical("protobuf: {}", m);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fleetgw ingest: MQTT 5 shared subscription → PostgreSQL (docs/backend.md)"};
  fleetgw::ingest::IngestOptions options;
  fleetgw::app::add_ingest_options(app, options);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("fleetgw-ingest"));
  spdlog::set_level(spdlog::level::from_str(options.log_level));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  google::protobuf::SetLogHandler(quiet_protobuf);
  try {
    return fleetgw::ingest::run_ingest(options);
  } catch (const std::exception& e) {
    std::cerr << "fleetgw ingest: " << e.what() << '\n';
    return 1;
  }
}
