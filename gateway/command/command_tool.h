// Operator tools: `fleetgw keygen` (an Ed25519 key pair for signing commands) and `fleetgw
// command` (sign one command, publish it, wait for its result). The CLI in gateway/app/ maps
// its flags onto these functions; they are also what tests and benchmarks use to sign.
//
// Contract:
//  * run_keygen() writes <prefix>.pem (PKCS#8 private key, mode 0600, never overwriting an
//    existing file) and <prefix>.pub (the base64 public key), and prints the config line
//    `<key-id> = "<base64 public key>"` for [command.trusted_keys]. Returns 0, or 1 with a
//    message on `err` (e.g. the file exists).
//  * run_command_tool(): validates the options (exit 2 with a message for usage errors: unknown
//    action, bad vehicle id, unreadable key, credentials over plain tcp:// ...), signs a Command
//    with a fresh random 128-bit command id, connects (clean session; TLS with server and
//    host-name verification when the URI is ssl://), subscribes to <prefix>/<V>/cmd/result
//    BEFORE publishing the SignedCommand to <prefix>/<V>/cmd at QoS 1, then waits up to
//    `timeout` for the Envelope whose CommandResult carries this command id (other results are
//    ignored). It prints that result as one JSON line on `out` and returns 0 only for
//    `succeeded`; 1 for failed / timeout / rejected; 3 when no answer came (or the broker could
//    not be reached). Diagnostics go to `err`; the password is never printed.
//  * This is an edge tool, not a gateway component: it reads the system clock (issued_at,
//    expiry, its own deadline) unless `wall_clock` is given.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/command/ed25519.h"
#include "motinova/can.h"

namespace fleetgw::v1 {
class Command;
}

namespace fleetgw::command {

using motinova::Micros;

int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out, std::ostream& err,
               std::string_view key_id = {});
int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out);

// Exit codes of run_command_tool().
inline constexpr int kExitSucceeded = 0;
inline constexpr int kExitNotSucceeded = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitNoAnswer = 3;

struct CommandToolOptions {
  std::string vehicle;                       // --vehicle V
  std::string lock;                          // --lock seat|battery|frame|...|vehicle
  std::string action;                        // --action lock|unlock
  std::filesystem::path key;                 // --key KEY.pem (Ed25519 private key)
  std::string key_id;                        // --key-id ID; default: the key file's stem
  std::string broker;                        // --broker tcp://host:1883 | ssl://host:8883
  std::string ca_file;                       // --ca-file
  std::string cert_file;                     // --cert-file (client certificate, mutual TLS)
  std::string key_file;                      // --key-file (client certificate's key)
  std::string username;                      // --username
  std::string password;                      // --password
  bool allow_plaintext_credentials = false;  // username/password over tcp:// (lab only)
  std::string topic_prefix = "fleet/v1";     // --topic-prefix
  std::chrono::seconds timeout{10};          // --timeout-s: wait for the result
  std::chrono::seconds expires_in{60};       // --expires-in-s: command validity
  std::string command_id;       // empty: fresh random id (tests and scripted retries may set it)
  std::ostream* out = nullptr;  // default std::cout
  std::ostream* err = nullptr;  // default std::cerr
  std::function<Micros()> wall_clock;  // default: system clock
};

int run_command_tool(const CommandToolOptions& options);

// Building blocks (tool, tests, benchmark).
// A fresh random command id: 32 lowercase hex characters.
std::string random_command_id();
// A Command for `lock` ("vehicle" = whole vehicle) and `action` ("lock"/"unlock"); nullopt for
// an unknown action or an empty lock.
std::optional<v1::Command> make_command(std::string_view vehicle, std::string_view lock,
                                        std::string_view action, Micros issued_at,
                                        Micros expires_at, std::string command_id);
// Serialized fleetgw.v1.SignedCommand: `command` serialized once, signed over exactly those bytes.
std::string sign_command(const v1::Command& command, const Ed25519PrivateKey& key,
                         std::string_view key_id);

}  // namespace fleetgw::command
