// The operator tool `fleetgw command`: sign one command, publish it, wait for its result. An
// edge tool of the CLI (it links Paho), kept out of the gateway's command library; signing and
// `fleetgw keygen` are in gateway/command/signing.h.
//
// Contract:
//  * run_command_tool(): validates the options (exit 2 with a message for usage errors: unknown
//    action, not exactly one action, bad vehicle id, unreadable key, credentials over plain
//    tcp:// ...), signs a Command -- lock/unlock (--lock + --action) or one MC action
//    (--speed-limit, --assist, --lights, --clear-trip, --power-off; issue 13) or one
//    diagnostic read (--diag BLOCK [--lock KIND] [--captured]; issue 29) --
//    with a fresh random 128-bit command id, connects (clean session; TLS with server and
//    host-name verification when the URI is ssl://), subscribes to <prefix>/<V>/cmd/result
//    BEFORE publishing the SignedCommand to <prefix>/<V>/cmd at QoS 1, then waits up to
//    `timeout` for the Envelope whose CommandResult carries this command id AND whose
//    command_sha256 is the SHA-256 of the exact Command bytes it signed. Other results are
//    ignored (counted on `err`): a result for a forged payload that copied our id, or any
//    result without the digest (a gateway older than this field), is never taken for ours. It
//    prints that result as one JSON line on `out` (a diagnostic read's decoded block as
//    "diagnostic": {block, node, source, requests_sent, note, messages: [{message, can_id,
//    command, data, heard_at, values: [{name, value, unit}]}]}) and returns 0 only for `succeeded`;
//    1 for failed / timeout / rejected; 3 when no answer came (or the broker could not be reached).
//    Diagnostics go to `err`; the password is never printed.
//  * It also subscribes to <prefix>/<V>/status, where the gateway's uplink keeps its retained
//    Status (online on connect, offline on a clean stop, the last will when the connection is
//    lost). When no result comes, the message on `err` says what the latest status there said:
//    "vehicle V offline since <ISO 8601 UTC>" (a clean stop: the Envelope's created_at_us),
//    "vehicle V offline: its connection was lost (last will); it had connected at <time>",
//    "vehicle V online (status of <time>) but it did not answer", or "vehicle V never seen (no
//    retained status on <topic>)". Exit status stays 3.
//  * MQTT 5 by default (`mqtt_version` "5"; "3.1.1" for a broker without it): the command's
//    publish carries a message expiry interval equal to its own validity (`expires_in`), so a
//    broker holding it for an offline vehicle drops it once the gateway would refuse it anyway,
//    and content type "application/x-protobuf; proto=fleetgw.v1.SignedCommand". A publish the
//    broker refuses (PUBACK reason code >= 0x80, e.g. an ACL) is reported with its reason code
//    and name, exit 3. Under 3.1.1 neither exists: a stale command reaches the gateway, which
//    rejects it as expired.
//  * --delegation (issue 28): the file must hold a SignedDelegation whose key id is the signing
//    key's (else exit 2 naming both); it travels in SignedCommand.delegation, outside the signed
//    bytes. --operator sets Command.operator_id inside them.
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

#include "gateway/command/signing.h"
#include "motinova/can.h"

namespace fleetgw::command {

using motinova::Micros;

// Exit codes of run_command_tool().
inline constexpr int kExitSucceeded = 0;
inline constexpr int kExitNotSucceeded = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitNoAnswer = 3;

struct CommandToolOptions {
  std::string vehicle;  // --vehicle V
  std::string lock;     // --lock seat|battery|frame|...|vehicle
  std::string action;   // --action lock|unlock
  // MC actions (issue 13); exactly one action per command, lock/unlock included.
  std::optional<int> speed_limit_kmh;  // --speed-limit KMH
  std::string assist;                  // --assist eco|norm|...
  std::string lights;                  // --lights on|off
  bool clear_trip = false;             // --clear-trip
  bool power_off = false;              // --power-off
  // Diagnostic reads (issue 29): --diag BLOCK (mc_settings, bms_cells, mc_lifetime, ...; the
  // lock for lock_model in --lock), --captured: the lifetime record last seen on the bus.
  std::string diag;
  bool captured = false;
  std::filesystem::path key;  // --key KEY.pem (Ed25519 private key)
  std::string key_id;  // --key-id ID; default: the delegation's key id, else the key file's stem
  // Issue 28: --delegation FILE (a SignedDelegation from `fleetgw keys delegate`) sent with the
  // command, for a key that is not in the gateways' [command.trusted_keys]; --operator NAME
  // goes into Command.operator_id (1..64 printable characters) and comes back in the result.
  std::filesystem::path delegation;
  std::string operator_id;
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
  std::string mqtt_version = "5";            // --mqtt-version 5|3.1.1
  std::string command_id;       // empty: fresh random id (tests and scripted retries may set it)
  std::ostream* out = nullptr;  // default std::cout
  std::ostream* err = nullptr;  // default std::cerr
  std::function<Micros()> wall_clock;  // default: system clock
};

int run_command_tool(const CommandToolOptions& options);

}  // namespace fleetgw::command
