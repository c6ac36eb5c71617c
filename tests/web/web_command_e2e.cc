// The console's command rig (web_command_e2e.h).
#include "tests/web/web_command_e2e.h"

#include <stdexcept>

#include "tests/support/gateway_config.h"
#include "tests/support/wait.h"
#include "tests/web/web_command_util.h"

namespace fleetgw::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

CommandRig::CommandRig(const std::string& vehicle) {
  broker.start();
  const fs::path key = dir.path() / "console-1.pem";
  make_key(key, fs::perms::owner_read | fs::perms::owner_write);
  stack = std::make_unique<ServeStack>(
      std::vector<std::string>{"--broker", broker.uri(), "--signing-key", key.string()});
  if (stack->add_operator("olga", "operator", "operator-password") != 0 ||
      stack->add_operator("vera", "viewer", "viewer-password") != 0) {
    throw std::runtime_error("--add-operator failed");
  }
  stack->insert_vehicle({.id = vehicle, .lat = 48.137, .lon = 11.575});

  GatewayConfig c(vehicle, dir.path() / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/parked.toml", 1);
  c.mqtt(broker.uri());
  c.add_line("command.trusted_keys", "console-1 = \"" + public_key_b64(key) + "\"");
  gateway = std::make_unique<GatewayProcess>(FLEETGW_BINARY, c.write(dir.path() / "fleetgw.toml"),
                                             std::vector<std::string>{"--duration", "300"});
  const bool ready = wait_until(
      [&] {
        return !gateway->running() || broker.log().find(vehicle + "/cmd") != std::string::npos;
      },
      30s, 20ms);
  if (!ready || !gateway->running()) {
    throw std::runtime_error("fleetgw run did not subscribe to its cmd topic:\n" + logs());
  }
}

CommandRig::~CommandRig() {
  if (gateway && gateway->running()) gateway->stop(10s);
}

std::string CommandRig::logs() const {
  return "--- fleetgw-serve:\n" + (stack ? stack->log() : "") + "\n--- fleetgw run:\n" +
         (gateway ? gateway->log() : "");
}

}  // namespace fleetgw::testing
