// Test support: the whole command path of the console for one simulated bike (issue 28): a
// real mosquitto, the console's Ed25519 key (openssl CLI), fleetgw-serve signing with it, and
// a real `fleetgw run` (parked scenario, real time) trusting that key.
//
// Contract:
//  * CommandRig(vehicle) starts everything and returns once the gateway has subscribed to its
//    cmd topic and heard its locks; std::runtime_error with the logs otherwise. Operators:
//    olga (operator, "operator-password"), vera (viewer, "viewer-password"). The vehicle has a
//    vehicle_state row at (48.137, 11.575) so the console knows it.
//  * logs() is the server's and the gateway's logs, for failure messages.
#pragma once

#include <memory>
#include <string>

#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/web/web_fixture.h"

namespace fleetgw::testing {

struct CommandRig {
  explicit CommandRig(const std::string& vehicle);
  ~CommandRig();
  std::string logs() const;

  MosquittoBroker broker;
  TempDir dir{"fleetgw-web-e2e"};
  std::unique_ptr<ServeStack> stack;
  std::unique_ptr<GatewayProcess> gateway;
};

}  // namespace fleetgw::testing
