// `fleetgw ingest` on the command line. The ingest runs as its own program, fleetgw-ingest
// (`fleetgw ingest ...` execs it, as `fleetgw watch` execs fleetgw-watch): it links libpq, which
// the service binary on the IoT node must not load (resident memory, docs/performance.md).
//
// Contract:
//  * add_ingest_options() defines the options once, for `fleetgw ingest --help` and the
//    fleetgw-ingest program alike; values are range-checked by CLI11 (usage errors exit 2).
//  * `fleetgw ingest ...` runs it through exec_subcommand_program (sibling_program.h).
#pragma once

#include <string_view>

#include "backend/ingest/ingest_options.h"

namespace CLI {
class App;
}

namespace fleetgw::app {

void add_ingest_options(CLI::App& app, ingest::IngestOptions& options);

}  // namespace fleetgw::app
