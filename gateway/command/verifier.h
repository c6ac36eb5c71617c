// CommandVerifier: decides whether a remote command payload may act on this vehicle. Pure: no
// I/O, no clock, no bus; the caller supplies `now`, whether the wall clock is synchronised and
// a "command id already seen" predicate (the SQLite journal in production).
//
// Contract:
//  * verify() turns the raw MQTT payload (a serialized fleetgw.v1.SignedCommand) into either a
//    VerifiedCommand or a Rejection (reason enum + human-readable detail). Checks, in order:
//      1. malformed            oversized, not a SignedCommand, no signature/key id, `command` not a
//                              Command, a required field missing or out of range
//      2. unknown_key          key_id not in the trusted keys
//      3. signature_invalid    not a valid Ed25519 signature of exactly the `command` bytes
//      4. wrong_vehicle        vehicle_id is not this vehicle
//      5. clock_unsynchronised the wall clock is not synchronised: expiry cannot be judged
//      6. expired              expires_at <= now
//      7. issued_in_future     issued_at > now + clock skew allowance
//      8. validity_too_long    expires_at - issued_at > max_validity (a standing unlock token)
//      9. replayed             the command id was already seen (and has not expired)
//     10. lock_not_fitted      the lock kind is not fitted to this bike (lock commands only)
//    A command carries either a lock action and target or one MC action (Command.mc_action,
//    issue 13); a mix of both, or an MC action with a missing/absurd value, is malformed. So is
//    a Command whose bytes carry more than one mc_action field (protobuf would keep the last
//    one silently: the bytes are scanned, issue 24) and a speed_limit without kmh -- which is
//    also what kmh 0 is on the wire (proto3 does not send a zero): 0 is never a limit.
//    The clock check comes before the time checks because they are meaningless on an
//    unsynchronised clock (it would report "issued in the future" instead of the real cause).
//  * Delegated keys (issue 28, delegation.h, docs/commands.md "Delegations"): a key id that is
//    not a trusted key but comes with SignedCommand.delegation is judged in three places:
//      2. delegation_invalid   instead of unknown_key: the delegation does not open (unknown
//                              root, the root's signature, malformed, for another key id)
//      3. signature_invalid    the delegation's public key does not verify the command bytes
//      4a. revoked             the delegation's serial or its key id is on a revocation list in
//                              force (a trusted key id too: a root may revoke one)
//      4b. out_of_scope        the command's action ("lock", "unlock", "speed_limit", ...) is
//                              not granted, then: this vehicle is not in its vehicle_ids, none
//                              of its groups in its groups, and not all_vehicles
//      4c. clock_unsynchronised  the window cannot be judged
//      4d. delegation_not_yet_valid  now < not_before
//      4e. delegation_expired  now >= not_after
//    then 5-10 as for any command. Checks 4a-4e are authorize(); their rejections are NOT
//    authenticated (Rejection::authenticated false, bound to payload_sha256): a revoked or
//    out-of-scope key must neither fill the journal nor pre-empt a command id. The operator_id
//    of a command whose signature verified is carried in every Rejection and VerifiedCommand.
//  * authenticate() runs checks 1-4 only: what the command service needs to recognise a
//    redelivery of a command it already journaled before judging its freshness again.
//  * authorize() runs 4a-4e on an authenticated command; it reads the revocation lists held by
//    the verifier (offer_revocations()/restore_revocations(): the caller persists them).
//  * Rejection::command_id is the id found in the payload when one could be parsed, even if the
//    command was not authentic (so an operator sees why their command was refused);
//    Rejection::authenticated tells whether the signature was valid. A VerifiedCommand and an
//    authenticated Rejection carry the SHA-256 of the received `command` bytes (sha256.h); an
//    unauthenticated Rejection carries only the SHA-256 of the whole payload: a forged payload
//    can copy a genuine command's bytes and id with a broken signature, so its answer must not
//    be bound to those bytes.
//  * The payload is parsed once: one SignedCommand parse, one Command parse.
//  * Received strings quoted in a detail (key id, vehicle id, lock kind) are untrusted: they go
//    through common::untrusted_excerpt (valid UTF-8, control characters escaped, cut on a
//    code-point boundary), so a detail is always safe to log, store and serialize.
//  * The constructor throws std::invalid_argument for a trusted or root key that is not a base64
//    raw Ed25519 public key (naming the key id), an invalid vehicle id or group.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"
#include "gateway/node/lock_actuator.h"
#include "motinova/can.h"

namespace fleetgw::command {

using motinova::Micros;
using namespace std::chrono_literals;

enum class RejectReason : std::uint8_t {
  // CommandVerifier
  kMalformed,
  kUnknownKey,
  kBadSignature,
  kWrongVehicle,
  kClockUnsynchronised,
  kExpired,
  kIssuedInFuture,
  kValidityTooLong,
  kReplayed,
  kLockNotFitted,
  // CommandService (after verification, before anything touches the bus)
  kLockOffline,
  kInterlockMoving,
  kInterlockMotionUnknown,
  kLockBusy,
  kShuttingDown,
  kStorageError,
  // MC actions (issue 13; mc_actions.h), before anything is written to the MC
  kMcOffline,
  kMcBusy,
  kMcStateUnknown,
  kOutOfRange,
  kUnknownAssistLevel,
  kLockMoving,
  // Geofence (issue 14): a ride-ending lock inside a no-parking zone, refused by configuration
  kNoParkingZone,
  // Geofence (issue 27): an unlock that would start a ride inside a no-start zone
  kNoStartZone,
  // Delegated keys (issue 28; delegation.h)
  kDelegationInvalid,
  kRevoked,
  kOutOfScope,
  kDelegationNotYetValid,
  kDelegationExpired,
  // Diagnostic reads (issue 29; diag_reader.h): another read is running
  kDiagBusy,
};
// The reason as sent in CommandResult.reason: "malformed", "unknown_key", "signature_invalid",
// "wrong_vehicle", "clock_unsynchronised", "expired", "issued_in_future", "validity_too_long",
// "replayed", "lock_not_fitted", "lock_offline", "interlock_moving", "interlock_motion_unknown",
// "lock_busy", "shutting_down", "storage_error", "mc_offline", "mc_busy", "mc_state_unknown",
// "out_of_range", "unknown_assist_level", "lock_moving", "no_parking_zone", "delegation_invalid",
// "revoked", "out_of_scope", "delegation_not_yet_valid", "delegation_expired", "diag_busy".
std::string_view reject_reason_name(RejectReason reason);

// "succeeded", "failed", "timeout", "rejected" or "unspecified": the result names used in logs,
// the journal and the operator tool's JSON.
std::string_view command_result_name(v1::CommandResultCode code);

struct Rejection {
  RejectReason reason = RejectReason::kMalformed;
  std::string detail;      // e.g. "expires_at 2024-06-01T08:00:00Z <= now 2024-06-01T08:00:05Z"
  std::string command_id;  // from the payload when parseable; may be empty
  bool authenticated = false;
  // Authenticated: SHA-256 of the received SignedCommand.command bytes (32 raw bytes).
  // Not authenticated: empty, and payload_sha256 is the SHA-256 of the whole payload (empty for
  // an oversized one). Copied into the CommandResult so it is bound to what was received.
  std::string command_sha256{};
  std::string payload_sha256{};
  // Command.operator_id (escaped, untrusted) once the command's signature verified; else empty.
  std::string operator_id{};
};

// The MC actions of issue 13 (Command.mc_action); kNone for a lock command.
enum class McActionKind : std::uint8_t {
  kNone,
  kSpeedLimit,
  kAssistLevel,
  kHeadlight,
  kClearTrip,
  kPowerOff,
};
// "speed_limit", "assist_level", "headlight", "clear_trip", "power_off" ("lock" for kNone).
std::string_view mc_action_name(McActionKind kind);

struct McRequest {
  McActionKind kind = McActionKind::kNone;
  std::uint32_t speed_limit_kmh = 0;  // kSpeedLimit: 1..255 (0 is refused)
  // kSpeedLimit of a remote command: speed_limit_kmh is the operator's cap, and what is written
  // is the limit in force with it (geofence::SpeedAuthority, issue 24). False for the gateway's
  // own writes, whose value is already that limit.
  bool sets_operator_cap = false;
  std::string assist_level;   // kAssistLevel: configured name, untrusted until resolved
  bool headlight_on = false;  // kHeadlight
};

// A diagnostic read (issue 29, Command.diagnostic_read); block UNSPECIFIED for other commands.
struct DiagRequest {
  v1::DiagnosticBlock block = v1::DIAGNOSTIC_BLOCK_UNSPECIFIED;
  std::string lock_kind;       // DIAGNOSTIC_BLOCK_LOCK_MODEL: the lock asked about
  bool last_captured = false;  // lifetime records: answer from the capture, send nothing
  bool requested() const { return block != v1::DIAGNOSTIC_BLOCK_UNSPECIFIED; }
};

// A command that passed authentication (and, from verify(), every check).
struct VerifiedCommand {
  std::string command_id;
  std::string vehicle_id;
  std::string key_id;
  Micros issued_at{0};
  Micros expires_at{0};
  node::LockTarget target = node::LockTarget::kLocked;  // lock -> kLocked, unlock -> kUnlocked
  bool whole_vehicle = false;
  std::string lock_kind;  // empty for whole_vehicle and MC actions
  McRequest mc;           // mc.kind != kNone: an MC action (no lock target)
  DiagRequest diag;       // diag.requested(): a diagnostic read (no lock target, no MC action)
  int lock_index = -1;    // 0-based LOCK k (node 7 + k); -1 for whole_vehicle or not yet resolved
  // SHA-256 of the signed Command bytes: binds the result to them and tells a redelivery (same
  // bytes) from a reused id (different bytes).
  std::string command_sha256;
  // Command.operator_id as received, escaped (common::untrusted_excerpt, 64 bytes): echoed in
  // every result.
  std::string operator_id;
  // The delegation it was signed under (a delegated key), and the SHA-256 of the whole payload
  // that an authorize() rejection is bound to.
  std::optional<Grant> delegation;
  std::string payload_sha256;
};

// The action name a delegation must grant for this command: "lock", "unlock", the MC
// action's name ("speed_limit", ...) or "diagnostics" for a diagnostic read.
std::string_view delegation_action(const VerifiedCommand& command);

using VerifyResult = std::variant<VerifiedCommand, Rejection>;

struct VerifierConfig {
  std::string vehicle_id;
  std::map<std::string, std::string> trusted_keys;  // key id -> base64 raw Ed25519 public key
  // Issue 28: the fleet's root keys (id -> base64 raw Ed25519 public key) that sign
  // delegations and revocation lists, and this vehicle's groups ([vehicle] groups).
  std::map<std::string, std::string> root_keys;
  std::vector<std::string> groups;
  Micros clock_skew = 30s;    // allowance for issued_at in the future
  Micros max_validity = 24h;  // longest accepted expires_at - issued_at
  std::array<std::string, motinova::kLockCount> lock_kinds{};  // "" = not fitted
  std::size_t max_payload_bytes = 4096;
};

class CommandVerifier {
 public:
  using SeenPredicate = std::function<bool(std::string_view command_id, Micros now)>;

  explicit CommandVerifier(VerifierConfig config);

  VerifyResult authenticate(std::span<const std::uint8_t> payload) const;
  VerifyResult verify(std::span<const std::uint8_t> payload, Micros now, bool clock_synchronised,
                      const SeenPredicate& seen) const;
  // Checks 4a-4e (revocation, scope, window) on an authenticated command.
  std::optional<Rejection> authorize(const VerifiedCommand& command, Micros now,
                                     bool clock_synchronised) const;
  // Checks 5-10 on an authenticated command.
  std::optional<Rejection> check(VerifiedCommand& command, Micros now, bool clock_synchronised,
                                 const SeenPredicate& seen) const;

  // Revocation lists (delegation.h Revocations), judged against the root keys.
  RevocationVerdict offer_revocations(std::span<const std::uint8_t> payload);
  std::vector<std::string> restore_revocations(std::string_view persisted);
  // The stored lists could not be read: delegated keys are refused until a list arrives.
  void revocations_unreadable(std::string why) { revocations_.mark_unknown(std::move(why)); }
  const Revocations& revocations() const { return revocations_; }
  const RootKeys& root_keys() const { return roots_; }
  const VehicleIdentity& identity() const { return identity_; }

  const VerifierConfig& config() const { return config_; }

 private:
  VerifierConfig config_;
  std::map<std::string, Ed25519PublicKey, std::less<>> keys_;
  RootKeys roots_;
  VehicleIdentity identity_;
  Revocations revocations_;
};

// Limits of the command id (chosen by the backend): 1..128 printable ASCII characters without
// space, so it is safe in topics, logs and the "command:<id>" lock-event cause.
bool is_valid_command_id(std::string_view id);

// "2024-06-01T08:00:00.000000Z" for details and logs.
std::string format_utc(Micros t);

}  // namespace fleetgw::command
