// The checks of the command verifier's trusted keys, as a list instead of a first-error throw,
// so that `fleetgw check-config` and `fleetgw run` report every bad key before the service starts.
//
// Contract: check_trusted_keys() never throws; it returns one problem per key id that is empty or
// whose value is not a base64 raw Ed25519 public key (32 bytes). An empty map is valid (commands
// are then all refused as unknown_key). The key text never appears in a message.
// check_root_keys() applies the same to [command.root_keys] and the id rule of signing.h.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace fleetgw::command {

struct TrustedKeyProblem {
  std::string key_id;   // the key under [command.trusted_keys] ("" for an empty id)
  std::string message;  // what is wrong, e.g. "not a base64 raw Ed25519 public key (32 bytes)"
};

std::vector<TrustedKeyProblem> check_trusted_keys(
    const std::map<std::string, std::string>& trusted_keys);

// The same for [command.root_keys] (issue 28), whose ids are also named in delegations and
// revocation lists: an id must be 1..64 characters of [A-Za-z0-9._-].
std::vector<TrustedKeyProblem> check_root_keys(const std::map<std::string, std::string>& root_keys);

}  // namespace fleetgw::command
