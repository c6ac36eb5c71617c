#include "gateway/cli/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace fleetgw::cli {

void setup_logging(std::string_view level) {
  auto logger = spdlog::stderr_color_mt("fleetgw");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(std::string(level)));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
}

}  // namespace fleetgw::cli
