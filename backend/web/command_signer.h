// The console's signing side of remote commands (issue 28): `fleetgw serve` holds its own
// Ed25519 key under a delegation issued by the fleet's root (proto/fleetgw/v1/keys.proto) and
// signs each command for the authenticated operator. The backend depends on proto/ only, so
// the few lines of signing are here (OpenSSL EVP), not borrowed from gateway/.
//
// Contract:
//  * CommandSigner(key, delegation, key_id) loads a PKCS#8 PEM Ed25519 private key (what
//    `fleetgw keygen` writes) and refuses it when the file is readable by its group or others.
//    With a delegation file (a serialized fleetgw.v1.SignedDelegation), the key id is the
//    delegation's and its public key must be the signing key's; without one, the key is a
//    plain trusted key ([command.trusted_keys]) named `key_id` (default: the file's stem).
//    std::runtime_error names the file and what is wrong.
//  * parse_command_request() turns the API's JSON ({"action": "lock", "lock_kind": "seat"},
//    {"action": "speed_limit", "kmh": 15}, ...) into a request, or an error text.
//  * out_of_scope() says why this server's own delegation does not cover an action on a
//    vehicle now (action not delegated, vehicle not named, outside the window), nullopt when
//    it does (or there is no delegation). A delegation scoped by groups only cannot be judged
//    here (the groups live in the gateways' configuration): the bike decides.
//  * sign() builds a fleetgw.v1.Command (random command_id, issued now, expires after `ttl`
//    but never after the delegation's not_after, operator_id = the operator) and signs exactly
//    its serialized bytes; the SignedCommand carries the delegation in field 4.
//    command_sha256 is the SHA-256 of those bytes (what the bike echoes in its result),
//    payload_sha256 that of the whole SignedCommand (echoed when the bike could not
//    authenticate it). Thread-safe (a fresh EVP context per call).
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

namespace fleetgw::v1 {
class SignedDelegation;
}

namespace fleetgw::web {

struct CommandRequest {
  std::string action;           // lock, unlock, speed_limit, assist_level, headlight, clear_trip,
                                // power_off: the delegation's action names
  std::string lock_kind;        // lock/unlock: one lock; empty = the whole vehicle
  std::uint32_t kmh = 0;        // speed_limit
  std::string level;            // assist_level
  bool on = false;              // headlight
  std::string summary() const;  // "lock whole vehicle", "speed_limit 15 km/h", ...
};

std::variant<CommandRequest, std::string> parse_command_request(const nlohmann::json& body);

struct SignedCommandBytes {
  std::string command_id;
  std::string payload;         // serialized fleetgw.v1.SignedCommand
  std::string command_sha256;  // hex
  std::string payload_sha256;  // hex
  std::int64_t issued_at_us = 0;
  std::int64_t expires_at_us = 0;
};

class CommandSigner {
 public:
  CommandSigner(const std::filesystem::path& key_file, const std::filesystem::path& delegation_file,
                std::string key_id);
  ~CommandSigner();
  CommandSigner(const CommandSigner&) = delete;
  CommandSigner& operator=(const CommandSigner&) = delete;

  const std::string& key_id() const { return key_id_; }
  std::optional<std::uint64_t> delegation_serial() const;
  std::optional<std::string> out_of_scope(const CommandRequest& r, std::string_view vehicle_id,
                                          std::int64_t now_us) const;
  SignedCommandBytes sign(const CommandRequest& r, std::string_view vehicle_id,
                          std::string_view operator_id, std::int64_t now_us,
                          std::chrono::seconds ttl) const;
  // What the console shows about the key: id, and the delegation's scope and window.
  nlohmann::json describe() const;
  // Documents signed with the same key (zone bundles, issue 28): the Ed25519 signature of
  // exactly `bytes`, and the root's delegation as it came (nullptr without --delegation).
  std::string sign_document(std::string_view bytes) const;
  const v1::SignedDelegation* signed_delegation() const;
  // Why the delegation does not let this server sign the document `action` ("zones") now.
  std::optional<std::string> document_out_of_scope(std::string_view action,
                                                   std::int64_t now_us) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string key_id_;
};

std::string hex_bytes(std::string_view bytes);

}  // namespace fleetgw::web
