// Subcommands served by a program of their own installed next to `fleetgw`: `fleetgw watch`
// (fleetgw-watch: protobuf reflection) and `fleetgw ingest` (fleetgw-ingest: libpq), kept out of
// the service binary that runs on the IoT node.
//
// Contract:
//  * exec_subcommand_program(program, command, argc, argv) replaces this process with
//    `program` given every argument that follows the word `command` in argv, the program found
//    next to the running executable (/proc/self/exe), else on PATH. It returns only on failure:
//    127, as a shell, after one line on stderr naming the program and where it was looked for.
#pragma once

#include <string_view>

namespace fleetgw::cli {

int exec_subcommand_program(std::string_view program, std::string_view command, int argc,
                            char** argv);

}  // namespace fleetgw::cli
