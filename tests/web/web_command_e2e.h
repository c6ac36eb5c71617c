// Test support: the whole command path of the console for one simulated bike (issue 28): a
// real mosquitto, the console's Ed25519 key (openssl CLI), fleetgw-serve signing with it, and
// a real `fleetgw run` (parked scenario, real time) trusting that key.
//
// Contract:
//  * With a RigDelegation the bike trusts only a root key (root-1) and the server runs with
//    --delegation (serial 7, key id console-1, valid from an hour ago to an hour ahead).
//  * CommandRig(vehicle) starts everything and returns once the gateway has subscribed to its
//    cmd topic and heard its locks; std::runtime_error with the logs otherwise. Operators:
//    olga (operator, "operator-password"), vera (viewer, "viewer-password"). The vehicle has a
//    vehicle_state row at (48.137, 11.575) so the console knows it.
//  * logs() is the server's and the gateway's logs, for failure messages.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {

// How the bike trusts the console's key: listed in [command.trusted_keys], or delegated by a
// fleet root listed in [command.root_keys] (actions, vehicle ids, groups of the delegation).
struct RigDelegation {
  std::vector<std::string> actions;
  std::vector<std::string> vehicle_ids;
  std::vector<std::string> groups;
};

struct CommandRig {
  explicit CommandRig(const std::string& vehicle,
                      std::optional<RigDelegation> delegation = std::nullopt);
  ~CommandRig();
  std::string logs() const;

  MosquittoBroker broker;
  TempDir dir{"fleetgw-web-e2e"};
  std::unique_ptr<ServeStack> stack;
  std::unique_ptr<GatewayProcess> gateway;
};

}  // namespace fleetgw::testing
