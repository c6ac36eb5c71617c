// Zone bundles: the signed, versioned fleetgw.v1.SignedZoneBundle an operator publishes, turned
// into the ZoneSet the engine evaluates -- or refused with a reason. No I/O (persistence is
// zone_file.h), no clock.
//
// Contract:
//  * compile_zones() validates a ZoneBundle and builds its ZoneSet. Refused, with a detail that
//    names the zone (index and id), the ring and the vertex: version 0, no issued_at, more than
//    `max_zones` zones or `max_vertices` vertices, a zone id that is not 1..64 of
//    [A-Za-z0-9._-] (the tools' id rule, command::is_valid_tool_id) or is repeated, a name over
//    128 bytes or not UTF-8, an unknown kind, no ring, lat/lon arrays of different lengths,
//    fewer than 3 distinct vertices (A-B-A-B has two), every vertex within 0.1 m of the line
//    from the ring's first vertex to the one farthest from it (no area worth the name), a
//    coordinate out of range, a ring spanning more than 180 degrees of longitude, a slow zone
//    without a limit in 1..255 km/h, a limit on another kind, a vehicle_id that is neither
//    empty nor a valid id. Self-intersecting rings are accepted (the even-odd rule gives them a
//    meaning).
//  * Bounded cost: the zone and vertex counts are checked before any shape is built, and each
//    shape's index is sized before it is allocated (zone_geometry.h). Judging a payload of P
//    bytes with V vertices in Z zones holds at most judging_bytes_bound(P, V, Z) on top of the
//    bundle already in force (the payload, its parse, the rings, the new ZoneSet), and the
//    ZoneSet kept in force at most zone_set_bytes_bound(V, Z); CPU is O(P + V) (one SHA-512 and
//    one Ed25519 verification of P bytes, one parse, 13 counting passes over the edges, one
//    index fill of <= 16 entries per vertex). Measured on the 100,000-vertex zig-zag (the
//    largest accepted bundle, every edge spanning the whole zone): docs/location.md.
//  * ZoneAuthority holds the bundle in force and judges each offer (a serialized
//    SignedZoneBundle, e.g. from the retained topic or the file at start-up). Checks, in order:
//      too_large          payload over `max_payload_bytes`
//      malformed          not a SignedZoneBundle, no signature / key id / bundle, bundle bytes
//                         not a ZoneBundle
//      unknown_key        key id not in the trusted keys (the same [command.trusted_keys] as
//                         commands)
//      signature_invalid  not an Ed25519 signature of exactly the bundle bytes
//      wrong_vehicle      the bundle's vehicle_id names another vehicle than the authority's
//                         (when it has one), or names none while it came on the vehicle's
//                         own topic (BundleTopic::kVehicle): a bundle signed for one bike is
//                         never accepted by another
//      not_newer          version lower than the one in force
//      version_conflict   same version as the one in force, different bundle bytes
//      invalid_zones      compile_zones() refused it
//    The same version with the same bytes is kAlreadyInForce (a retained message delivered
//    again on every reconnect), not an error. A refused offer never changes what is in force.
//  * Received strings quoted in a detail (key id, zone id, name) go through
//    common::untrusted_excerpt: a detail is always safe to log, store and publish.
//  * The constructor throws std::invalid_argument for a trusted key that is not a base64 raw
//    Ed25519 public key, naming the key id.
//  * sign_zone_bundle() serializes the bundle once and signs exactly those bytes (the operator
//    tool and the tests).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>

#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"
#include "gateway/geofence/zone_engine.h"

namespace fleetgw::v1 {
class ZoneBundle;
}  // namespace fleetgw::v1

namespace fleetgw::geofence {

struct BundleLimits {
  std::size_t max_payload_bytes = 4u << 20;
  std::size_t max_zones = 4096;
  std::size_t max_vertices = 100'000;
  std::size_t max_name_bytes = 128;
};

// The bounds stated in the contract above, in bytes (allocator overhead included as a
// constant per allocation).
std::size_t zone_set_bytes_bound(std::size_t vertices, std::size_t zones);
std::size_t judging_bytes_bound(std::size_t payload_bytes, std::size_t vertices, std::size_t zones);

// The ZoneSet, or the reason it was refused.
std::variant<ZoneSet, std::string> compile_zones(const v1::ZoneBundle& bundle,
                                                 const BundleLimits& limits = {});

enum class BundleOutcome : std::uint8_t { kAccepted, kAlreadyInForce, kRefused };
enum class BundleRefusal : std::uint8_t {
  kNone,
  kTooLarge,
  kMalformed,
  kUnknownKey,
  kBadSignature,
  kNotNewer,
  kVersionConflict,
  kInvalidZones,
  kWrongVehicle,
  // Issue 28: a key delegated by a root (set_delegated_check); names as for commands.
  kDelegationInvalid,
  kRevoked,
  kOutOfScope,
  kClockUnsynchronised,
  kDelegationNotYetValid,
  kDelegationExpired,
};
// Where a bundle came from: the fleet-wide topic (or the stored file, or an operator's check),
// or the vehicle's own topic, which accepts only bundles signed for this vehicle.
enum class BundleTopic : std::uint8_t { kFleet, kVehicle };
// "accepted", "already_in_force", "refused".
std::string_view bundle_outcome_name(BundleOutcome outcome);
// "", "too_large", "malformed", "unknown_key", "signature_invalid", "not_newer",
// "version_conflict", "invalid_zones", "wrong_vehicle".
std::string_view bundle_refusal_name(BundleRefusal reason);

struct BundleVerdict {
  BundleOutcome outcome = BundleOutcome::kRefused;
  BundleRefusal reason = BundleRefusal::kNone;
  std::string detail;          // why, for the log and `fleetgw zones check`
  std::uint64_t version = 0;   // the offered version, once authenticated
  std::uint64_t in_force = 0;  // the version in force after the offer (0: none)
  bool accepted() const { return outcome == BundleOutcome::kAccepted; }
};

struct BundleInForce {
  std::string payload;        // the SignedZoneBundle as received: what is persisted
  std::string bundle_sha256;  // of the signed bundle bytes
  std::string key_id;
  std::shared_ptr<const ZoneSet> zones;
  std::string vehicle_id;  // the vehicle it was signed for; empty: fleet-wide
};

class ZoneAuthority {
 public:
  // trusted_keys: key id -> base64 raw Ed25519 public key, as [command.trusted_keys].
  // vehicle_id: this gateway's [vehicle] id; empty (an operator's check with no vehicle given)
  // accepts a bundle named for any vehicle.
  explicit ZoneAuthority(const std::map<std::string, std::string>& trusted_keys,
                         BundleLimits limits = {}, std::string vehicle_id = {});

  BundleVerdict offer(std::span<const std::uint8_t> payload,
                      BundleTopic topic = BundleTopic::kFleet);
  BundleVerdict offer(std::string_view payload, BundleTopic topic = BundleTopic::kFleet);
  const std::optional<BundleInForce>& in_force() const { return in_force_; }
  // Issue 28: how a bundle whose key id is not trusted but carries SignedZoneBundle.delegation
  // is judged (command::check_delegated with the action "zones": root, scope, window,
  // revocations); unset: such a bundle is unknown_key as before.
  using DelegatedCheck = std::function<command::DelegatedCheck(
      const v1::SignedDelegation&, std::string_view key_id,
      std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature)>;
  void set_delegated_check(DelegatedCheck check) { delegated_check_ = std::move(check); }

 private:
  // Why a bundle naming `named` and received on `topic` is not for this vehicle, if it is not.
  std::optional<std::string> wrong_vehicle(std::string_view named, BundleTopic topic) const;

  BundleLimits limits_;
  std::string vehicle_id_;
  std::map<std::string, command::Ed25519PublicKey, std::less<>> keys_;
  std::optional<BundleInForce> in_force_;
  DelegatedCheck delegated_check_;
};

// Serialized SignedZoneBundle over `bundle` serialized once.
std::string sign_zone_bundle(const v1::ZoneBundle& bundle, const command::Ed25519PrivateKey& key,
                             std::string_view key_id);

}  // namespace fleetgw::geofence
