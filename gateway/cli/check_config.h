// The one validation path of a configuration: `fleetgw check-config FILE` and `fleetgw run
// --config FILE` both go through load_runnable_config(), so check-config says OK exactly when
// run would start (short of the devices themselves: the CAN interface, the broker, the disk).
//
// Contract:
//  * load_runnable_config() loads the file (config::load_config: syntax, types, ranges, unknown
//    keys, nan/inf, a directory instead of a file), applies `adjust` (the run command's
//    overrides), then runs check_runnable(). It throws config::ConfigError listing EVERY problem,
//    each as "file:line: key: what" (line omitted for a key the file does not set).
//  * check_runnable() never throws. It applies the checks that the service's components would
//    otherwise apply one at a time at start-up, with their own code where they have it:
//      - can.replay_file exists and is a readable file (transport replay),
//      - sim.scenario loads (transport sim; with sim.nmea_pty it has a [[route]]),
//        can.udp_local/udp_remote are address:port (udp),
//      - the directory of storage.path exists and storage.path is not a directory (the service
//        never creates directories),
//      - [mqtt] (when enabled): uplink::check_uplink_config (URI scheme, no user information,
//        no credentials over tcp://, readable TLS files, ...),
//      - [command.trusted_keys]: command::check_trusted_keys.
//  * run_check_config() prints "FILE: OK" (exit 0), or every problem and a count (exit 1).
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "gateway/config/config.h"

namespace fleetgw::cli {

std::vector<std::string> check_runnable(const config::Config& config);

config::Config load_runnable_config(const std::filesystem::path& file,
                                    const std::function<void(config::Config&)>& adjust = {});

int run_check_config(const std::filesystem::path& file, std::ostream& out, std::ostream& err);

// Prints a ConfigError's problems and their count (the format both commands use).
void print_config_error(const config::ConfigError& e, std::ostream& err);

}  // namespace fleetgw::cli
