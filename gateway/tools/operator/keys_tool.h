// `fleetgw keys` (issue 28): the fleet's root key, the delegations it signs and its revocation
// lists, as files. The rules a gateway applies to them are in docs/commands.md "Delegations";
// the checks are gateway/command/delegation.h, so a file this tool writes is judged by exactly
// the code that judges it on the bike.
//
// Contract (every run_* returns 0 done, 1 failed -- a file exists, cannot be written, a
// signature does not verify --, 2 usage error; messages on `err` name the option and what is
// wrong; nothing is ever overwritten):
//  * run_keys_root(): a root key pair, PREFIX.pem (PKCS#8, mode 0600) and PREFIX.pub (base64),
//    and on `out` the line for [command.root_keys]: `<id> = "<base64>"` (id: --key-id, default
//    the prefix's file name).
//  * run_keys_delegate(): a SignedDelegation file. The delegate's public key is --public-key
//    (a .pub file or the base64 text) or a fresh pair written to --new-key PREFIX (.pem 0600,
//    .pub). Refused before anything is written: an action that is not one of
//    delegation.h's known names, no action, no scope, --all-vehicles with --vehicles/--groups,
//    an invalid id, serial 0, a holder over 128 bytes, not_before >= not_after, a time that is
//    not an ISO 8601 UTC time. The Delegation is serialized once and signed by the root over
//    exactly those bytes; the written file is opened again with the gateway's RootKeys::open()
//    before the tool reports success.
//  * run_keys_revoke(): a SignedRevocationList file (version > 0; serials > 0; valid key ids).
//  * run_keys_show(): what a delegation or revocation list file says, for people (received
//    strings escaped), and whether it is well-formed; with `root_keys` (a gateway's
//    [command.root_keys]) whether the root's signature verifies -- exit 1 when it does not or
//    the file is neither kind.
//  * run_keys_publish_revocations(): the list published retained, QoS 1, on
//    <prefix>/<vehicle>/revocations for each --vehicle (the gateway's uplink subscribes there
//    when it has root keys). Exit 3 when the broker cannot be reached or does not acknowledge.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <map>
#include <string>
#include <vector>

#include "motinova/can.h"

namespace fleetgw::tools {

using motinova::Micros;

struct KeysRootOptions {
  std::filesystem::path out_prefix;
  std::string key_id;  // empty: the prefix's file name
};

struct KeysDelegateOptions {
  std::filesystem::path root_pem;
  std::string root_id;
  std::string key_id;
  std::string public_key;                // a .pub file, or the base64 raw key
  std::filesystem::path new_key_prefix;  // or: a fresh pair written here
  std::vector<std::string> actions;
  std::vector<std::string> vehicles;
  std::vector<std::string> groups;
  bool all_vehicles = false;
  std::string not_before;  // ISO 8601 UTC; empty: now
  std::string not_after;   // ISO 8601 UTC
  std::uint64_t serial = 0;
  std::string holder;
  std::filesystem::path out;
  Micros now{0};  // issued_at and the default not_before
};

struct KeysRevokeOptions {
  std::filesystem::path root_pem;
  std::string root_id;
  std::uint64_t version = 0;
  std::vector<std::uint64_t> serials;
  std::vector<std::string> key_ids;
  std::filesystem::path out;
  Micros now{0};
};

struct KeysShowOptions {
  std::filesystem::path file;
  std::map<std::string, std::string> root_keys;  // empty: the signature is not checked
  bool check_signature = false;                  // a configuration was given
  Micros now{0};
};

struct KeysPublishOptions {
  std::filesystem::path file;
  std::vector<std::string> vehicles;
  std::string broker;
  std::string ca_file, cert_file, key_file;
  std::string username, password;
  bool allow_plaintext_credentials = false;
  std::string topic_prefix = "fleet/v1";
  std::chrono::seconds timeout{10};
};

int run_keys_root(const KeysRootOptions& options, std::ostream& out, std::ostream& err);
int run_keys_delegate(const KeysDelegateOptions& options, std::ostream& out, std::ostream& err);
int run_keys_revoke(const KeysRevokeOptions& options, std::ostream& out, std::ostream& err);
int run_keys_show(const KeysShowOptions& options, std::ostream& out, std::ostream& err);
int run_keys_publish_revocations(const KeysPublishOptions& options, std::ostream& out,
                                 std::ostream& err);

}  // namespace fleetgw::tools
