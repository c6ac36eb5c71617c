// The fleetgw command line: one binary, subcommands (CLI11).
//
// Contract: run_cli() parses argv, runs one subcommand and returns the process exit status.
// Usage errors exit 2 with CLI11's message; a subcommand's own errors are printed to stderr.
#pragma once

namespace fleetgw::cli {

int run_cli(int argc, char** argv);

}  // namespace fleetgw::cli
