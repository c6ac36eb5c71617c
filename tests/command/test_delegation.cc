// Delegated keys on the bike (issue 28): the pure verifier judges a command signed by a key the
// fleet's root delegated -- each refusal with its own reason, in the documented order -- and an
// old configuration with trusted keys only keeps working.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <variant>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/keys.pb.h"
#include "fleetgw/v1/zones.pb.h"
#include "gateway/command/base64.h"
#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/command/verifier.h"
#include "gateway/geofence/zone_bundle.h"

namespace fleetgw::command {
namespace {

using namespace std::chrono_literals;

constexpr Micros kDelegationNow{1'800'000'000'000'000};  // 2027-01-15, synchronised

struct DelegationRig {
  Ed25519PrivateKey root = Ed25519PrivateKey::generate();
  Ed25519PrivateKey other_root = Ed25519PrivateKey::generate();
  Ed25519PrivateKey delegate = Ed25519PrivateKey::generate();
  Ed25519PrivateKey trusted = Ed25519PrivateKey::generate();

  VerifierConfig config() const {
    VerifierConfig c;
    c.vehicle_id = "bike-0042";
    c.groups = {"berlin-north", "ebikes"};
    c.trusted_keys = {{"backend-1", trusted.public_key().base64()}};
    c.root_keys = {{"root-1", root.public_key().base64()}};
    c.lock_kinds = {"seat", "frame", "", "", ""};
    return c;
  }

  // A delegation of `delegate` as "console-1" for lock/unlock on bike-0042, valid around
  // kDelegationNow.
  v1::Delegation grant() const {
    v1::Delegation d;
    d.set_serial(7);
    d.set_key_id("console-1");
    // public_key() returns by value: keep it alive while its raw bytes are read.
    const auto public_key = delegate.public_key();
    const auto& raw = public_key.raw();
    d.set_public_key(std::string(raw.begin(), raw.end()));
    d.add_actions("lock");
    d.add_actions("unlock");
    d.add_vehicle_ids("bike-0042");
    d.set_not_before_us((kDelegationNow - 1h).count());
    d.set_not_after_us((kDelegationNow + 1h).count());
    d.set_issued_at_us((kDelegationNow - 2h).count());
    d.set_holder("console-berlin");
    return d;
  }

  v1::Command command(std::string_view action = "unlock", std::string_view vehicle = "bike-0042",
                      std::string id = "cmd-1") const {
    auto c = make_command(vehicle, "seat", action, kDelegationNow - 1s, kDelegationNow + 60s,
                          std::move(id));
    c->set_operator_id("alice");
    return *c;
  }

  // The command signed by `key` as `key_id` with `delegation` (serialized SignedDelegation).
  static std::string payload(const v1::Command& c, const Ed25519PrivateKey& key,
                             std::string_view key_id, const std::string& delegation) {
    return sign_for_sending(c, key, key_id, delegation).payload;
  }
  std::string delegated(const v1::Delegation& d, const v1::Command& c) const {
    return payload(c, delegate, d.key_id(), sign_delegation(d, root, "root-1"));
  }
};

VerifyResult verify_delegated(const CommandVerifier& v, const std::string& payload,
                              Micros now = kDelegationNow, bool synced = true) {
  return v.verify({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, now,
                  synced, nullptr);
}

// The rejection's "<code>: <detail>" as a result would carry it; "accepted" when verified.
std::string outcome_of(const VerifyResult& r) {
  if (std::holds_alternative<VerifiedCommand>(r)) return "accepted";
  const auto& rej = std::get<Rejection>(r);
  return std::string(reject_reason_name(rej.reason)) + ": " + rej.detail;
}

std::string reason_of_result(const VerifyResult& r) {
  if (std::holds_alternative<VerifiedCommand>(r)) return "accepted";
  return std::string(reject_reason_name(std::get<Rejection>(r).reason));
}

std::span<const std::uint8_t> span_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

TEST(Delegation, CommandUnderAValidDelegationIsAcceptedAndNamesItsOperator) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto r = verify_delegated(v, rig.delegated(rig.grant(), rig.command()));
  ASSERT_EQ(outcome_of(r), "accepted");
  const auto& c = std::get<VerifiedCommand>(r);
  EXPECT_EQ(c.key_id, "console-1");
  EXPECT_EQ(c.operator_id, "alice");
  ASSERT_TRUE(c.delegation.has_value());
  EXPECT_EQ(c.delegation->serial, 7u);
  EXPECT_EQ(c.delegation->root_key_id, "root-1");
}

TEST(Delegation, ExpiredDelegationIsRefused) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.set_not_before_us((kDelegationNow - 2h).count());
  d.set_not_after_us((kDelegationNow - 1h).count());
  const auto r = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(r), "delegation_expired") << outcome_of(r);
  EXPECT_NE(outcome_of(r).find("expired at 2027-01-15T"), std::string::npos) << outcome_of(r);
  // The boundary: valid up to, not including, not_after.
  d.set_not_after_us(kDelegationNow.count());
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))),
            "delegation_expired");
  d.set_not_after_us(kDelegationNow.count() + 1);
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))), "accepted");
}

TEST(Delegation, DelegationNotYetValidIsRefused) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.set_not_before_us((kDelegationNow + 10min).count());
  d.set_not_after_us((kDelegationNow + 1h).count());
  const auto r = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(r), "delegation_not_yet_valid") << outcome_of(r);
  d.set_not_before_us(kDelegationNow.count());  // valid from not_before on
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))), "accepted");
}

TEST(Delegation, UnsynchronisedClockCannotJudgeTheWindow) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto r = verify_delegated(v, rig.delegated(rig.grant(), rig.command()), kDelegationNow,
                                  /*synced=*/false);
  EXPECT_EQ(reason_of_result(r), "clock_unsynchronised") << outcome_of(r);
  EXPECT_NE(outcome_of(r).find("window"), std::string::npos) << outcome_of(r);
}

TEST(Delegation, ActionOutsideTheScopeIsRefusedNamingTheAction) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.clear_actions();
  d.add_actions("lock");
  const auto r = verify_delegated(v, rig.delegated(d, rig.command("unlock")));
  EXPECT_EQ(reason_of_result(r), "out_of_scope");
  EXPECT_NE(outcome_of(r).find("action 'unlock'"), std::string::npos) << outcome_of(r);
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("lock")))),
            "accepted");
  // An MC action is judged by its own name.
  auto mc = make_mc_command("bike-0042", "speed_limit", "15", kDelegationNow - 1s,
                            kDelegationNow + 60s, "mc-1");
  const auto m = verify_delegated(v, rig.delegated(d, *mc));
  EXPECT_EQ(reason_of_result(m), "out_of_scope");
  EXPECT_NE(outcome_of(m).find("action 'speed_limit'"), std::string::npos) << outcome_of(m);
  // A name this gateway does not know never widens the scope.
  d.add_actions("everything");
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("unlock")))),
            "out_of_scope");
}

TEST(Delegation, VehicleOutsideTheScopeIsRefusedNamingTheVehicle) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.clear_vehicle_ids();
  d.add_vehicle_ids("bike-0001");
  const auto r = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(r), "out_of_scope");
  EXPECT_NE(outcome_of(r).find("vehicle 'bike-0042'"), std::string::npos) << outcome_of(r);
}

TEST(Delegation, GroupScopeMatchesOnlyTheVehiclesGroups) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.clear_vehicle_ids();
  d.add_groups("munich");
  const auto wrong = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(wrong), "out_of_scope");
  EXPECT_NE(outcome_of(wrong).find("berlin-north"), std::string::npos) << outcome_of(wrong);
  d.add_groups("berlin-north");
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))), "accepted");
  // The same delegation on a gateway without that group.
  auto config = rig.config();
  config.groups = {"ebikes"};
  CommandVerifier other(config);
  EXPECT_EQ(reason_of_result(verify_delegated(other, rig.delegated(d, rig.command()))),
            "out_of_scope");
}

TEST(Delegation, AllVehiclesCoversEveryVehicleButIsNeverImplied) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto d = rig.grant();
  d.clear_vehicle_ids();
  d.set_all_vehicles(true);
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))), "accepted");
  d.set_all_vehicles(false);  // no scope at all: not "every vehicle"
  const auto r = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(r), "delegation_invalid");
  EXPECT_NE(outcome_of(r).find("names no vehicle"), std::string::npos) << outcome_of(r);
}

TEST(Delegation, RevokedSerialIsRefused) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto payload = rig.delegated(rig.grant(), rig.command());
  ASSERT_EQ(reason_of_result(verify_delegated(v, payload)), "accepted");
  v1::RevocationList list;
  list.set_version(1);
  list.set_issued_at_us(kDelegationNow.count());
  list.add_revoked_serials(7);
  ASSERT_TRUE(
      v.offer_revocations(span_of(sign_revocation_list(list, rig.root, "root-1"))).accepted());
  const auto r = verify_delegated(v, payload);
  EXPECT_EQ(reason_of_result(r), "revoked");
  EXPECT_NE(outcome_of(r).find("delegation 7 of root 'root-1'"), std::string::npos)
      << outcome_of(r);
  // Not authentic-and-journaled: bound to the payload, and it still names the operator.
  const auto& rej = std::get<Rejection>(r);
  EXPECT_FALSE(rej.authenticated);
  EXPECT_FALSE(rej.payload_sha256.empty());
  EXPECT_EQ(rej.operator_id, "alice");
  // Another serial of the same root is untouched.
  auto d = rig.grant();
  d.set_serial(8);
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command()))), "accepted");
}

TEST(Delegation, RevokedKeyIdIsRefusedWhateverItsDelegationAndAsATrustedKey) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  v1::RevocationList list;
  list.set_version(3);
  list.set_issued_at_us(kDelegationNow.count());
  list.add_revoked_key_ids("console-1");
  list.add_revoked_key_ids("backend-1");
  ASSERT_TRUE(
      v.offer_revocations(span_of(sign_revocation_list(list, rig.root, "root-1"))).accepted());
  auto d = rig.grant();
  d.set_serial(99);  // a fresh delegation of the revoked key
  const auto r = verify_delegated(v, rig.delegated(d, rig.command()));
  EXPECT_EQ(reason_of_result(r), "revoked");
  EXPECT_NE(outcome_of(r).find("key 'console-1'"), std::string::npos) << outcome_of(r);
  const auto t =
      verify_delegated(v, DelegationRig::payload(rig.command(), rig.trusted, "backend-1", {}));
  EXPECT_EQ(reason_of_result(t), "revoked") << outcome_of(t);
}

TEST(Delegation, ForgedRootSignatureIsInvalid) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  // Signed by another key that claims to be root-1.
  const auto forged = sign_delegation(rig.grant(), rig.other_root, "root-1");
  const auto r =
      verify_delegated(v, DelegationRig::payload(rig.command(), rig.delegate, "console-1", forged));
  EXPECT_EQ(reason_of_result(r), "delegation_invalid");
  EXPECT_NE(outcome_of(r).find("root signature"), std::string::npos) << outcome_of(r);
  EXPECT_FALSE(std::get<Rejection>(r).authenticated);
  // A genuine delegation with one byte of it changed (a widened scope, say).
  v1::SignedDelegation sd;
  sd.ParseFromString(sign_delegation(rig.grant(), rig.root, "root-1"));
  std::string bytes = sd.delegation();
  bytes.back() ^= 1;
  sd.set_delegation(bytes);
  const auto t = verify_delegated(
      v, DelegationRig::payload(rig.command(), rig.delegate, "console-1", sd.SerializeAsString()));
  EXPECT_EQ(reason_of_result(t), "delegation_invalid") << outcome_of(t);
}

TEST(Delegation, DelegationForAnotherKeyIdIsInvalid) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  // console-2 presents console-1's delegation (and console-1's public key does not sign for it).
  const auto r =
      verify_delegated(v, DelegationRig::payload(rig.command(), rig.delegate, "console-2",
                                                 sign_delegation(rig.grant(), rig.root, "root-1")));
  EXPECT_EQ(reason_of_result(r), "delegation_invalid");
  EXPECT_NE(outcome_of(r).find("is for key 'console-1', not for the signing key 'console-2'"),
            std::string::npos)
      << outcome_of(r);
}

TEST(Delegation, CommandNotSignedByTheDelegatedKeyIsSignatureInvalid) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto other = Ed25519PrivateKey::generate();
  const auto r =
      verify_delegated(v, DelegationRig::payload(rig.command(), other, "console-1",
                                                 sign_delegation(rig.grant(), rig.root, "root-1")));
  EXPECT_EQ(reason_of_result(r), "signature_invalid");
  EXPECT_NE(outcome_of(r).find("delegated key 'console-1'"), std::string::npos) << outcome_of(r);
}

TEST(Delegation, UnknownRootIsInvalid) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto r = verify_delegated(
      v, DelegationRig::payload(rig.command(), rig.delegate, "console-1",
                                sign_delegation(rig.grant(), rig.other_root, "root-9")));
  EXPECT_EQ(reason_of_result(r), "delegation_invalid");
  EXPECT_NE(outcome_of(r).find("root key 'root-9' is not in [command.root_keys]"),
            std::string::npos)
      << outcome_of(r);
  // Without any root configured (an old configuration), the same answer.
  auto config = rig.config();
  config.root_keys.clear();
  CommandVerifier old(config);
  EXPECT_EQ(reason_of_result(verify_delegated(old, rig.delegated(rig.grant(), rig.command()))),
            "delegation_invalid");
}

TEST(Delegation, UnknownKeyWithoutDelegationIsStillUnknownKey) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  const auto r =
      verify_delegated(v, DelegationRig::payload(rig.command(), rig.delegate, "console-1", {}));
  EXPECT_EQ(outcome_of(r), "unknown_key: key id 'console-1' is not trusted");
}

TEST(Delegation, TrustedKeysKeepTheirUnscopedMeaning) {
  DelegationRig rig;
  auto config = rig.config();
  config.root_keys.clear();
  config.groups.clear();
  CommandVerifier v(config);
  auto c = rig.command("unlock");
  c.clear_operator_id();
  const auto r = verify_delegated(v, DelegationRig::payload(c, rig.trusted, "backend-1", {}));
  ASSERT_EQ(outcome_of(r), "accepted");
  EXPECT_TRUE(std::get<VerifiedCommand>(r).operator_id.empty());
  EXPECT_FALSE(std::get<VerifiedCommand>(r).delegation.has_value());
}

TEST(Delegation, ChecksRunInTheDocumentedOrder) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  v1::RevocationList list;
  list.set_version(1);
  list.set_issued_at_us(kDelegationNow.count());
  list.add_revoked_serials(7);
  ASSERT_TRUE(
      v.offer_revocations(span_of(sign_revocation_list(list, rig.root, "root-1"))).accepted());
  // Revoked AND out of scope AND expired, on an unsynchronised clock: revoked first.
  auto d = rig.grant();
  d.clear_actions();
  d.add_actions("lock");
  d.set_not_before_us((kDelegationNow - 3h).count());
  d.set_not_after_us((kDelegationNow - 2h).count());
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("unlock")),
                                              kDelegationNow, false)),
            "revoked");
  // Not revoked: out of scope before the clock.
  d.set_serial(8);
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("unlock")),
                                              kDelegationNow, false)),
            "out_of_scope");
  // In scope: the clock, then the window, then the command's own expiry.
  EXPECT_EQ(reason_of_result(
                verify_delegated(v, rig.delegated(d, rig.command("lock")), kDelegationNow, false)),
            "clock_unsynchronised");
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("lock")))),
            "delegation_expired");
  // wrong_vehicle (check 4) comes before all of them.
  EXPECT_EQ(
      reason_of_result(verify_delegated(v, rig.delegated(d, rig.command("lock", "bike-0001")))),
      "wrong_vehicle");
}

TEST(Delegation, OperatorIdIsEscapedAndCut) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto c = rig.command();
  c.set_operator_id("mallory\n[ERROR] forged line " + std::string(100, 'x'));
  const auto r = verify_delegated(v, rig.delegated(rig.grant(), c));
  ASSERT_EQ(outcome_of(r), "accepted");
  const auto& op = std::get<VerifiedCommand>(r).operator_id;
  EXPECT_EQ(op.find('\n'), std::string::npos);
  EXPECT_LE(op.size(), 64u);
  EXPECT_EQ(op.rfind("mallory\\n[ERROR]", 0), 0u) << op;
}

TEST(RevocationList, AcceptedOnlyFromARootWithAGreaterVersion) {
  DelegationRig rig;
  CommandVerifier v(rig.config());
  auto list_payload = [&](std::uint64_t version, const Ed25519PrivateKey& key,
                          std::string_view root_id, std::uint64_t serial = 7) {
    v1::RevocationList list;
    list.set_version(version);
    list.set_issued_at_us(kDelegationNow.count());
    list.add_revoked_serials(serial);
    return sign_revocation_list(list, key, root_id);
  };
  const auto forged = v.offer_revocations(span_of(list_payload(5, rig.other_root, "root-1")));
  EXPECT_EQ(forged.reason, "signature_invalid");
  EXPECT_EQ(v.offer_revocations(span_of(list_payload(5, rig.other_root, "root-9"))).reason,
            "unknown_key");
  EXPECT_EQ(v.offer_revocations(span_of(std::string("junk"))).reason, "malformed");
  EXPECT_EQ(v.revocations().version(), 0u);

  const auto v2 = list_payload(2, rig.root, "root-1");
  EXPECT_TRUE(v.offer_revocations(span_of(v2)).accepted());
  EXPECT_EQ(v.offer_revocations(span_of(v2)).outcome, RevocationOutcome::kAlreadyInForce);
  EXPECT_EQ(v.offer_revocations(span_of(list_payload(1, rig.root, "root-1", 8))).reason,
            "not_newer");
  EXPECT_EQ(v.offer_revocations(span_of(list_payload(2, rig.root, "root-1", 8))).reason,
            "version_conflict");
  EXPECT_EQ(v.revocations().version(), 2u);
  // A newer list replaces the old one: serial 7 is no longer revoked, 8 is.
  EXPECT_TRUE(v.offer_revocations(span_of(list_payload(3, rig.root, "root-1", 8))).accepted());
  EXPECT_EQ(reason_of_result(verify_delegated(v, rig.delegated(rig.grant(), rig.command()))),
            "accepted");

  // Persisted and restored into a fresh verifier (a restart): the same list in force.
  CommandVerifier restarted(rig.config());
  EXPECT_TRUE(restarted.restore_revocations(v.revocations().persisted()).empty());
  EXPECT_EQ(restarted.revocations().version(), 3u);
  auto d = rig.grant();
  d.set_serial(8);
  EXPECT_EQ(reason_of_result(verify_delegated(restarted, rig.delegated(d, rig.command()))),
            "revoked");
  // A tampered store restores nothing, and fails closed: a revoked key must not come back
  // because its list was damaged. Delegated keys are refused until a root's list arrives.
  CommandVerifier tampered(rig.config());
  EXPECT_EQ(tampered.restore_revocations("AAAA\n").size(), 1u);
  EXPECT_EQ(tampered.revocations().version(), 0u);
  EXPECT_EQ(reason_of_result(verify_delegated(tampered, rig.delegated(rig.grant(), rig.command()))),
            "revoked");
  EXPECT_TRUE(
      tampered.offer_revocations(span_of(list_payload(4, rig.root, "root-1", 9))).accepted());
  EXPECT_EQ(reason_of_result(verify_delegated(tampered, rig.delegated(rig.grant(), rig.command()))),
            "accepted");
  // A list of a root that is no longer configured is only dropped: nothing else is unknown.
  CommandVerifier other_roots(rig.config());
  const auto foreign = list_payload(1, rig.other_root, "root-9");
  EXPECT_EQ(other_roots.restore_revocations(encode_base64(span_of(foreign)) + "\n").size(), 1u);
  EXPECT_EQ(other_roots.revocations().unknown(), std::nullopt);
  EXPECT_EQ(
      reason_of_result(verify_delegated(other_roots, rig.delegated(rig.grant(), rig.command()))),
      "accepted");
}

}  // namespace
}  // namespace fleetgw::command

// Zone bundles signed under a delegation (issue 28): the same rules, with the action "zones".
namespace fleetgw::command {
namespace {

std::string delegated_bundle(const DelegationRig& rig, const v1::Delegation& d) {
  v1::ZoneBundle b;
  b.set_version(1);
  b.set_issued_at_us(kDelegationNow.count());
  auto* z = b.add_zones();
  z->set_id("area");
  z->set_kind(v1::ZONE_KIND_OPERATING_AREA);
  auto* ring = z->add_rings();
  for (const auto& [lat, lon] : {std::pair{525000000, 134000000}, std::pair{525100000, 134000000},
                                 std::pair{525100000, 134100000}}) {
    ring->add_lat_e7(lat);
    ring->add_lon_e7(lon);
  }
  v1::SignedZoneBundle s;
  s.ParseFromString(geofence::sign_zone_bundle(b, rig.delegate, d.key_id()));
  s.mutable_delegation()->ParseFromString(sign_delegation(d, rig.root, "root-1"));
  return s.SerializeAsString();
}

TEST(DelegationZones, BundleNeedsTheZonesActionAndAValidDelegation) {
  DelegationRig rig;
  const RootKeys roots(rig.config().root_keys);
  const Revocations none;
  const VehicleIdentity me{"bike-0042", {"berlin-north"}};
  geofence::ZoneAuthority authority({}, {}, "bike-0042");
  authority.set_delegated_check([&](const v1::SignedDelegation& sd, std::string_view key_id,
                                    std::span<const std::uint8_t> bytes,
                                    std::span<const std::uint8_t> sig) {
    return check_delegated(sd, key_id, bytes, sig, "zones", me, kDelegationNow, true, roots, none);
  });
  auto d = rig.grant();  // lock, unlock: no "zones"
  const auto refused = authority.offer(delegated_bundle(rig, d));
  EXPECT_EQ(geofence::bundle_refusal_name(refused.reason), "out_of_scope") << refused.detail;
  d.add_actions("zones");
  d.set_not_after_us((kDelegationNow - 1s).count());
  d.set_not_before_us((kDelegationNow - 2h).count());
  const auto expired = authority.offer(delegated_bundle(rig, d));
  EXPECT_EQ(geofence::bundle_refusal_name(expired.reason), "delegation_expired") << expired.detail;
  d.set_not_after_us((kDelegationNow + 1h).count());
  const auto ok = authority.offer(delegated_bundle(rig, d));
  EXPECT_TRUE(ok.accepted()) << geofence::bundle_refusal_name(ok.reason) << ": " << ok.detail;
  // Without the hook (an old gateway): unknown_key, as before.
  geofence::ZoneAuthority old({}, {}, "bike-0042");
  EXPECT_EQ(geofence::bundle_refusal_name(old.offer(delegated_bundle(rig, d)).reason),
            "unknown_key");
}

}  // namespace
}  // namespace fleetgw::command
