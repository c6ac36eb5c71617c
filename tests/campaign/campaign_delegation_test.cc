// Campaigns signed under a root's delegation (issues 28/29): accepted only when the delegation
// is a valid root's, grants the action "campaign" for this vehicle, is within its window and
// is not revoked; each failure refused with the name commands and zone bundles use.
#include <gtest/gtest.h>

#include "campaign_test_util.h"
#include "fleetgw/v1/campaign.pb.h"
#include "fleetgw/v1/keys.pb.h"
#include "gateway/campaign/campaign_authority.h"
#include "gateway/command/delegation.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kSecond;

constexpr motinova::Micros kHour = 3600 * kSecond;

// A root, a delegate, the authority of bike-7 judging with the root and a revocation list.
struct CampaignDelegationRig {
  command::Ed25519PrivateKey root = command::Ed25519PrivateKey::generate();
  command::Ed25519PrivateKey other_root = command::Ed25519PrivateKey::generate();
  command::Ed25519PrivateKey delegate = command::Ed25519PrivateKey::generate();
  command::RootKeys roots{{{"root-1", root.public_key().base64()}}};
  command::Revocations revocations;
  command::VehicleIdentity me{"bike-7", {"berlin-north"}};
  motinova::Micros now = kDay0 + kSecond;

  CampaignAuthority authority() const {
    CampaignAuthority a({}, "bike-7", {"berlin-north"});
    a.set_delegated_check([this](const v1::SignedDelegation& sd, std::string_view key_id,
                                 std::span<const std::uint8_t> bytes,
                                 std::span<const std::uint8_t> sig) {
      return command::check_delegated(sd, key_id, bytes, sig, "campaign", me, now, true, roots,
                                      revocations);
    });
    return a;
  }

  // "console-1" for "campaign" on bike-7, valid for an hour around now.
  v1::Delegation grant() const {
    v1::Delegation d;
    d.set_serial(7);
    d.set_key_id("console-1");
    // public_key() returns by value: keep it alive while its raw bytes are read.
    const auto public_key = delegate.public_key();
    const auto& raw = public_key.raw();
    d.set_public_key(std::string(raw.begin(), raw.end()));
    d.add_actions("campaign");
    d.add_vehicle_ids("bike-7");
    d.set_not_before_us((now - kHour).count());
    d.set_not_after_us((now + kHour).count());
    d.set_issued_at_us((now - 2 * kHour).count());
    d.set_holder("console-berlin");
    return d;
  }

  // base_campaign() signed by the delegate under `d` signed by `by` as "root-1".
  std::string campaign(const v1::Delegation& d, const command::Ed25519PrivateKey& by) const {
    v1::SignedCampaign s;
    s.ParseFromString(sign_campaign(test::base_campaign(), delegate, d.key_id()));
    s.mutable_delegation()->ParseFromString(command::sign_delegation(d, by, "root-1"));
    return s.SerializeAsString();
  }
  std::string campaign(const v1::Delegation& d) const { return campaign(d, root); }
};

std::string reason_of(const CampaignVerdict& v) {
  return std::string(campaign_refusal_name(v.reason)) + ": " + v.detail;
}

TEST(CampaignDelegation, AcceptedUnderAValidDelegationWithTheCampaignAction) {
  CampaignDelegationRig rig;
  auto a = rig.authority();
  const auto v = a.offer(rig.campaign(rig.grant()), rig.now);
  ASSERT_TRUE(v.accepted()) << reason_of(v);
  EXPECT_EQ(a.in_force().at("cells-hot").key_id, "console-1");
  // Without the hook (no [command.root_keys]): unknown_key.
  CampaignAuthority old({}, "bike-7");
  EXPECT_EQ(campaign_refusal_name(old.offer(rig.campaign(rig.grant()), rig.now).reason),
            "unknown_key");
}

TEST(CampaignDelegation, DelegationWithoutTheCampaignActionIsOutOfScope) {
  CampaignDelegationRig rig;
  auto a = rig.authority();
  auto d = rig.grant();
  d.clear_actions();
  d.add_actions("zones");
  const auto v = a.offer(rig.campaign(d), rig.now);
  EXPECT_EQ(campaign_refusal_name(v.reason), "out_of_scope") << v.detail;
  EXPECT_TRUE(a.in_force().empty());
}

TEST(CampaignDelegation, ExpiredDelegationIsRefused) {
  CampaignDelegationRig rig;
  auto a = rig.authority();
  auto d = rig.grant();
  d.set_not_before_us((rig.now - 2 * kHour).count());
  d.set_not_after_us((rig.now - kSecond).count());
  const auto v = a.offer(rig.campaign(d), rig.now);
  EXPECT_EQ(campaign_refusal_name(v.reason), "delegation_expired") << v.detail;
  d.set_not_before_us((rig.now + kHour).count());
  d.set_not_after_us((rig.now + 2 * kHour).count());
  EXPECT_EQ(campaign_refusal_name(a.offer(rig.campaign(d), rig.now).reason),
            "delegation_not_yet_valid");
}

TEST(CampaignDelegation, RevokedSerialIsRefused) {
  CampaignDelegationRig rig;
  v1::RevocationList list;
  list.set_version(3);
  list.set_issued_at_us(rig.now.count());
  list.add_revoked_serials(7);
  const auto payload = command::sign_revocation_list(list, rig.root, "root-1");
  ASSERT_TRUE(
      rig.revocations
          .offer({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, rig.roots)
          .accepted());
  auto a = rig.authority();
  const auto v = a.offer(rig.campaign(rig.grant()), rig.now);
  EXPECT_EQ(campaign_refusal_name(v.reason), "revoked") << v.detail;
  EXPECT_TRUE(a.in_force().empty());
}

TEST(CampaignDelegation, ForgedRootSignatureOrDelegateSignatureIsRefused) {
  CampaignDelegationRig rig;
  auto a = rig.authority();
  const auto forged = a.offer(rig.campaign(rig.grant(), rig.other_root), rig.now);
  EXPECT_EQ(campaign_refusal_name(forged.reason), "delegation_invalid") << forged.detail;
  // The delegation is valid, but the campaign is signed by another key than the delegate's.
  v1::SignedCampaign s;
  s.ParseFromString(sign_campaign(test::base_campaign(), rig.other_root, "console-1"));
  s.mutable_delegation()->ParseFromString(
      command::sign_delegation(rig.grant(), rig.root, "root-1"));
  EXPECT_EQ(campaign_refusal_name(a.offer(s.SerializeAsString(), rig.now).reason),
            "signature_invalid");
  EXPECT_TRUE(a.in_force().empty());
}

}  // namespace
}  // namespace fleetgw::campaign
