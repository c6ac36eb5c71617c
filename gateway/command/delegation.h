// Delegated keys (issue 28): a fleet ROOT key ([command.root_keys], kept offline) signs a
// fleetgw.v1.Delegation that lets another key sign commands and documents within a scope and a
// time window; the root withdraws delegations and keys with a signed, versioned RevocationList.
// Pure: no I/O, no clock (the caller passes `now` and whether its clock is synchronised). Used by
// the command verifier (verifier.h) and the zone bundles (gateway/geofence/zone_bundle.h) alike.
//
// Contract (the rules are in docs/commands.md "Delegations"):
//  * RootKeys::open() judges a SignedDelegation offered with a signature by `signer_key_id`, in
//    this order, each failure kInvalid with a detail naming what: root_key_id empty or not a
//    configured root; the root's Ed25519 signature over exactly `delegation` bytes; those bytes
//    not a Delegation; serial 0; key_id not 1..64 of [A-Za-z0-9._-] or not `signer_key_id`;
//    public_key not a raw Ed25519 key (32 bytes); no action; no scope (vehicle_ids, groups,
//    all_vehicles all empty); a vehicle id or group that is not a valid id; not_before_us <= 0
//    or not_after_us <= not_before_us; holder over 128 bytes. On success the Grant (plain data)
//    and the delegate's public key.
//  * judge() applies the time-independent checks first, then the clock: revoked (the
//    delegation's serial by a list of ITS root, or its key id by any root's list), out_of_scope
//    (the action not in actions -- unknown names never widen a scope --, then the vehicle: its
//    id in vehicle_ids, one of its groups in groups, or all_vehicles), clock_unsynchronised,
//    delegation_not_yet_valid (now < not_before), delegation_expired (now >= not_after).
//  * Revocations holds at most one list per root key. offer() accepts a serialized
//    SignedRevocationList only when: at most kMaxRevocationBytes, it parses, root_key_id is a
//    configured root and its signature verifies over exactly the `revocations` bytes, version
//    > 0, issued_at > 0, every revoked key id a valid id, and version greater than the list
//    held for that root (the same version with the same bytes is "already in force", not an
//    error). A refused offer changes nothing. persisted()/restore() carry the accepted lists
//    across restarts (restore re-verifies each one: a tampered store or a root removed from the
//    configuration loses its list).
//  * Received strings quoted in a detail are escaped to printable ASCII and cut (64 bytes).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "gateway/command/ed25519.h"
#include "motinova/can.h"

namespace fleetgw::v1 {
class Delegation;
class RevocationList;
class SignedDelegation;
}  // namespace fleetgw::v1

namespace fleetgw::command {

using motinova::Micros;

enum class DelegationRefusal : std::uint8_t {
  kInvalid,              // "delegation_invalid"
  kRevoked,              // "revoked"
  kOutOfScope,           // "out_of_scope"
  kClockUnsynchronised,  // "clock_unsynchronised"
  kNotYetValid,          // "delegation_not_yet_valid"
  kExpired,              // "delegation_expired"
};
std::string_view delegation_refusal_name(DelegationRefusal reason);

struct DelegationProblem {
  DelegationRefusal reason = DelegationRefusal::kInvalid;
  std::string detail;
};

// What a root's valid signature granted (a checked Delegation, plain data).
struct Grant {
  std::string root_key_id;
  std::uint64_t serial = 0;
  std::string key_id;
  std::vector<std::string> actions;
  std::vector<std::string> vehicle_ids;
  std::vector<std::string> groups;
  bool all_vehicles = false;
  Micros not_before{0};
  Micros not_after{0};
  std::string holder;
};

struct OpenedDelegation {
  Grant grant;
  Ed25519PublicKey public_key;
};

// Who judges: this gateway's vehicle id and its groups ([vehicle] id, groups).
struct VehicleIdentity {
  std::string id;
  std::vector<std::string> groups;
};

inline constexpr std::size_t kMaxHolderBytes = 128;
inline constexpr std::size_t kMaxRevocationBytes = 64 * 1024;

class RootKeys {
 public:
  RootKeys() = default;
  // root key id -> base64 raw Ed25519 public key; throws std::invalid_argument naming a bad one.
  explicit RootKeys(const std::map<std::string, std::string>& config);

  bool empty() const { return keys_.empty(); }
  const Ed25519PublicKey* find(std::string_view id) const;
  std::variant<OpenedDelegation, DelegationProblem> open(
      const v1::SignedDelegation& signed_delegation, std::string_view signer_key_id) const;

 private:
  std::map<std::string, Ed25519PublicKey, std::less<>> keys_;
};

// One root's accepted list.
struct RevocationEntry {
  std::uint64_t version = 0;
  std::int64_t issued_at_us = 0;
  std::set<std::uint64_t> serials;
  std::set<std::string, std::less<>> key_ids;
  std::string payload;  // the SignedRevocationList as received (what is persisted)
};

enum class RevocationOutcome : std::uint8_t { kAccepted, kAlreadyInForce, kRefused };

struct RevocationVerdict {
  RevocationOutcome outcome = RevocationOutcome::kRefused;
  // Refused: "too_large", "malformed", "unknown_key", "signature_invalid", "not_newer",
  // "version_conflict"; empty otherwise.
  std::string reason;
  std::string detail;
  std::uint64_t version = 0;  // the offered version, once authenticated
  bool accepted() const { return outcome == RevocationOutcome::kAccepted; }
};

class Revocations {
 public:
  RevocationVerdict offer(std::span<const std::uint8_t> payload, const RootKeys& roots);
  // Why `key_id` (under the delegation `serial` of `root_key_id`, or a trusted key when
  // root_key_id is empty) is revoked, or nullopt.
  std::optional<std::string> revoked(std::string_view root_key_id, std::uint64_t serial,
                                     std::string_view key_id) const;
  // The highest version in force over every root (0: none); for `fleetgw status`.
  std::uint64_t version() const;
  const std::map<std::string, RevocationEntry, std::less<>>& lists() const { return lists_; }
  // The accepted lists as one text (one base64 SignedRevocationList per line).
  std::string persisted() const;
  // Offers every list of a persisted() text again; returns the problems (one per refused line).
  // A stored line that is not a list a root of today's configuration signed (not base64,
  // malformed, a broken signature: the store was damaged or tampered with) leaves the lists
  // UNKNOWN; a line of a root no longer configured is only dropped.
  std::vector<std::string> restore(std::string_view text, const RootKeys& roots);
  // The stored lists could not be read at all (an I/O error): unknown as well.
  void mark_unknown(std::string why) { unknown_ = std::move(why); }
  // Fail closed: while the lists are unknown, every DELEGATED key counts as revoked (trusted
  // keys of the configuration keep working, so an operator is never locked out), until a
  // root's list is accepted again (the broker's retained copy arrives at the next connect).
  const std::optional<std::string>& unknown() const { return unknown_; }

 private:
  std::map<std::string, RevocationEntry, std::less<>> lists_;  // by root key id
  std::optional<std::string> unknown_;  // why the stored lists could not be restored
};

// The delegation's scope, window and revocation judged for `action` on `vehicle` at `now`
// (the order of the contract above); nullopt: allowed.
std::optional<DelegationProblem> judge(const Grant& grant, std::string_view action,
                                       const VehicleIdentity& vehicle, Micros now,
                                       bool clock_synchronised, const Revocations& revocations);

// The whole check of a document signed under a delegation: open() (with `signer_key_id`), the
// delegate's signature over `signed_bytes` (kInvalid is NOT used for it: nullopt `signature_ok`
// tells the caller to answer signature_invalid), then judge().
struct DelegatedCheck {
  std::optional<DelegationProblem> problem;  // set: refused for this reason
  bool signature_invalid = false;            // the delegate's signature did not verify
  std::optional<Grant> grant;                // set when the delegation opened
};
DelegatedCheck check_delegated(const v1::SignedDelegation& signed_delegation,
                               std::string_view signer_key_id,
                               std::span<const std::uint8_t> signed_bytes,
                               std::span<const std::uint8_t> signature, std::string_view action,
                               const VehicleIdentity& vehicle, Micros now, bool clock_synchronised,
                               const RootKeys& roots, const Revocations& revocations);

// The content rules of RootKeys::open() alone (serial, key id, public key, actions, scope, ids,
// window, holder): what `fleetgw keys show` checks without the root's public key.
std::optional<std::string> delegation_content_problem(const v1::Delegation& delegation);

// Issuing (`fleetgw keys`, the tests): the message serialized ONCE and signed over exactly
// those bytes by the root; serialized SignedDelegation / SignedRevocationList.
std::string sign_delegation(const v1::Delegation& delegation, const Ed25519PrivateKey& root,
                            std::string_view root_key_id);
std::string sign_revocation_list(const v1::RevocationList& list, const Ed25519PrivateKey& root,
                                 std::string_view root_key_id);

// Valid names of Delegation.actions (what `fleetgw keys delegate` accepts).
bool is_known_delegation_action(std::string_view action);
std::string_view known_delegation_actions();  // "lock, unlock, ..., zones, campaign"

}  // namespace fleetgw::command
