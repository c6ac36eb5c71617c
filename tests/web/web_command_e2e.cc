// The console's command rig (web_command_e2e.h).
#include "tests/web/web_command_e2e.h"

#include <fstream>
#include <stdexcept>

#include "tests/support/gateway_config.h"
#include "tests/support/wait.h"
#include "tests/web/web_command_util.h"

namespace fleetgw::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

CommandRig::CommandRig(const std::string& vehicle, std::optional<RigDelegation> delegation) {
  broker.start();
  const fs::path key = dir.path() / "console-1.pem";
  const auto mode = fs::perms::owner_read | fs::perms::owner_write;
  make_key(key, mode);
  std::vector<std::string> args = {"--broker", broker.uri(), "--signing-key", key.string()};
  const fs::path root = dir.path() / "root-1.pem";
  if (delegation) {
    make_key(root, mode);
    v1::Delegation d;
    d.set_serial(7);
    d.set_key_id("console-1");
    d.set_public_key(public_key(key));
    for (const auto& a : delegation->actions) d.add_actions(a);
    for (const auto& v : delegation->vehicle_ids) d.add_vehicle_ids(v);
    for (const auto& g : delegation->groups) d.add_groups(g);
    d.set_not_before_us(now_us() - 3'600'000'000LL);
    d.set_not_after_us(now_us() + 3'600'000'000LL);
    d.set_issued_at_us(now_us());
    d.set_holder("console e2e");
    const fs::path file = dir.path() / "console-1.delegation";
    std::ofstream(file, std::ios::binary) << sign_delegation(root, "root-1", d);
    args.insert(args.end(), {"--delegation", file.string()});
    // The root admins' revocation lists are verified against (revocation_routes.cc).
    args.insert(args.end(), {"--root-key", "root-1=" + public_key_b64(root)});
  }
  stack = std::make_unique<ServeStack>(args);
  if (stack->add_operator("olga", "operator", "operator-password") != 0 ||
      stack->add_operator("vera", "viewer", "viewer-password") != 0) {
    throw std::runtime_error("--add-operator failed");
  }
  stack->insert_vehicle({.id = vehicle, .lat = 48.137, .lon = 11.575});

  GatewayConfig c(vehicle, dir.path() / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/parked.toml", 1);
  c.mqtt(broker.uri());
  if (delegation) {
    c.add_line("command.root_keys", "root-1 = \"" + public_key_b64(root) + "\"");
  } else {
    c.add_line("command.trusted_keys", "console-1 = \"" + public_key_b64(key) + "\"");
  }
  gateway = std::make_unique<GatewayProcess>(FLEETGW_BINARY, c.write(dir.path() / "fleetgw.toml"),
                                             std::vector<std::string>{"--duration", "1800"});
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
