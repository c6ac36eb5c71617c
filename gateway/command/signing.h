// Signing commands and keys: `fleetgw keygen` (an Ed25519 key pair for signing commands) and the
// building blocks the operator tool, the tests and the benchmarks sign with. No network here:
// the MQTT side of `fleetgw command` lives in gateway/tools/operator/command_tool.h.
//
// Contract:
//  * run_keygen() writes <prefix>.pem (PKCS#8 private key, mode 0600, never overwriting an
//    existing file) and <prefix>.pub (the base64 public key), and prints the config line
//    `<key-id> = "<base64 public key>"` for [command.trusted_keys]. Returns 0, or 1 with a
//    message on `err` (e.g. the file exists).
//  * sign_command() serializes the Command ONCE and signs exactly those bytes; it can report
//    the SHA-256 of those bytes, which the gateway's result carries back (command_sha256).
//  * result_answers() is the one rule by which a sender recognises the answer to what it sent:
//    same command id AND either command_sha256 equal to the digest of the bytes it signed, or
//    (a payload the gateway found unauthentic) payload_sha256 equal to the digest of the exact
//    payload it published. A forgery that copies the id -- even the command bytes -- with a
//    broken signature gets neither.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/command/ed25519.h"
#include "motinova/can.h"

namespace fleetgw::v1 {
class Command;
class CommandResult;
}  // namespace fleetgw::v1

namespace fleetgw::command {

using motinova::Micros;

int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out, std::ostream& err,
               std::string_view key_id = {});
int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out);

// 1..64 characters of [A-Za-z0-9._-]: key ids and vehicle ids the tools accept.
bool is_valid_tool_id(std::string_view id);

// A fresh random command id: 32 lowercase hex characters.
std::string random_command_id();
// A Command for `lock` ("vehicle" = whole vehicle) and `action` ("lock"/"unlock"); nullopt for
// an unknown action or an empty lock.
std::optional<v1::Command> make_command(std::string_view vehicle, std::string_view lock,
                                        std::string_view action, Micros issued_at,
                                        Micros expires_at, std::string command_id);
// A Command carrying one MC action (issue 13): `action` "speed_limit" (value: km/h, 1..255),
// "assist_level" (value: a level name), "headlight" (value: "on" or "off"), "clear_trip" or
// "power_off" (value ignored); nullopt for an unknown action or a bad value.
std::optional<v1::Command> make_mc_command(std::string_view vehicle, std::string_view action,
                                           std::string_view value, Micros issued_at,
                                           Micros expires_at, std::string command_id);
// Serialized fleetgw.v1.SignedCommand: `command` serialized once, signed over exactly those
// bytes; `command_sha256` (optional) receives the raw SHA-256 of those bytes.
std::string sign_command(const v1::Command& command, const Ed25519PrivateKey& key,
                         std::string_view key_id, std::string* command_sha256 = nullptr);

struct SentCommand {
  std::string payload;         // serialized SignedCommand, as published
  std::string command_sha256;  // SHA-256 of its signed Command bytes
};
// sign_command() with both digests' inputs kept, for result_answers().
SentCommand sign_for_sending(const v1::Command& command, const Ed25519PrivateKey& key,
                             std::string_view key_id);
// The same with the key's delegation (issue 28) in SignedCommand.delegation: a serialized
// fleetgw.v1.SignedDelegation as `fleetgw keys delegate` writes it (empty: none).
SentCommand sign_for_sending(const v1::Command& command, const Ed25519PrivateKey& key,
                             std::string_view key_id, std::string_view signed_delegation);

bool result_answers(const v1::CommandResult& result, std::string_view command_id,
                    const SentCommand& sent);

}  // namespace fleetgw::command
