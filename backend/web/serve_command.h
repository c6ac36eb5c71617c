// `fleetgw serve` on the command line: the options, defined once for `fleetgw serve --help`
// (the gateway CLI validates them, then execs fleetgw-serve, as for `fleetgw ingest`) and for
// the fleetgw-serve program itself. Header-only dependencies: CLI11 and serve_options.h.
#pragma once

#include "backend/web/serve_options.h"

namespace CLI {
class App;
}

namespace fleetgw::web {

void add_serve_options(CLI::App& app, ServeOptions& options);

}  // namespace fleetgw::web
