// Logging set-up for the fleetgw binary: spdlog to stderr with the configured level (the
// journal captures stderr under systemd).
#pragma once

#include <string_view>

namespace fleetgw::cli {

void setup_logging(std::string_view level);

}  // namespace fleetgw::cli
