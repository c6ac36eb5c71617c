#include "gateway/command/key_check.h"

#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"

namespace fleetgw::command {

std::vector<TrustedKeyProblem> check_trusted_keys(
    const std::map<std::string, std::string>& trusted_keys) {
  std::vector<TrustedKeyProblem> problems;
  for (const auto& [id, text] : trusted_keys) {
    if (id.empty()) {
      problems.push_back({id, "empty key id"});
    } else if (!Ed25519PublicKey::from_base64(text)) {
      problems.push_back({id, "not a base64 raw Ed25519 public key (32 bytes)"});
    }
  }
  return problems;
}

std::vector<TrustedKeyProblem> check_root_keys(
    const std::map<std::string, std::string>& root_keys) {
  std::vector<TrustedKeyProblem> problems;
  for (const auto& [id, text] : root_keys) {
    if (!is_valid_tool_id(id)) {
      problems.push_back({id, "a root key id is 1..64 characters of [A-Za-z0-9._-]"});
    } else if (!Ed25519PublicKey::from_base64(text)) {
      problems.push_back({id, "not a base64 raw Ed25519 public key (32 bytes)"});
    }
  }
  return problems;
}

}  // namespace fleetgw::command
