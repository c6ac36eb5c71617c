// Which signed campaigns a gateway runs: expired, forged, older, over-budget, foreign campaigns
// are refused with their reason; a retained one delivered again is already in force.
#include <gtest/gtest.h>

#include "campaign_test_util.h"
#include "gateway/campaign/campaign_authority.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kSecond;

struct Signer {
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  std::map<std::string, std::string> trusted() const {
    return {{"eng", key.public_key().base64()}};
  }
  std::string sign(const v1::Campaign& c) const { return sign_campaign(c, key, "eng"); }
};

CampaignVerdict offer(CampaignAuthority& a, const std::string& payload,
                      CampaignTopic topic = CampaignTopic::kFleet) {
  return a.offer(payload, kDay0 + kSecond, topic);
}

TEST(CampaignAuthority, AcceptsOnceThenAlreadyInForce) {
  Signer s;
  CampaignAuthority a(s.trusted(), "bike-7");
  const auto payload = s.sign(test::base_campaign());
  EXPECT_EQ(offer(a, payload).outcome, CampaignOutcome::kAccepted);
  EXPECT_EQ(offer(a, payload).outcome, CampaignOutcome::kAlreadyInForce);
  EXPECT_EQ(a.in_force().size(), 1u);
}

TEST(CampaignAuthority, RefusalsCarryTheirReason) {
  Signer s, forger;
  CampaignAuthority a(s.trusted(), "bike-7", {"berlin-north"});
  auto reason = [&](const std::string& payload, CampaignTopic topic = CampaignTopic::kFleet) {
    return std::string(campaign_refusal_name(offer(a, payload, topic).reason));
  };
  // Forged: signed by another key under the trusted id.
  EXPECT_EQ(reason(sign_campaign(test::base_campaign(), forger.key, "eng")), "signature_invalid");
  EXPECT_EQ(reason(sign_campaign(test::base_campaign(), forger.key, "mallory")), "unknown_key");
  EXPECT_EQ(reason("not a campaign"), "malformed");
  auto expired = test::base_campaign();
  expired.set_start_us((kDay0 - 20 * kSecond).count());
  expired.set_end_us(kDay0.count());
  EXPECT_EQ(reason(s.sign(expired)), "expired");
  auto unknown = test::base_campaign();
  unknown.add_signals("bms.cells.voltage_of_cell_17");
  const auto v = offer(a, s.sign(unknown));
  EXPECT_EQ(campaign_refusal_name(v.reason), "invalid_campaign");
  EXPECT_NE(v.detail.find("signals[1]: unknown signal"), std::string::npos);
  auto other = test::base_campaign();
  other.mutable_target()->set_all_vehicles(false);
  other.mutable_target()->add_vehicle_ids("bike-8");
  other.mutable_target()->add_groups("paris");
  EXPECT_EQ(reason(s.sign(other)), "not_for_this_vehicle");
  other.mutable_target()->add_groups("berlin-north");
  EXPECT_EQ(reason(s.sign(other)), "");  // accepted through its group
  // The fleet's campaign on this vehicle's own topic must name it.
  auto fleet = test::base_campaign();
  fleet.set_id("fleet-wide");
  EXPECT_EQ(reason(s.sign(fleet), CampaignTopic::kVehicle), "not_for_this_vehicle");
  EXPECT_EQ(a.in_force().size(), 1u);
}

TEST(CampaignAuthority, OlderAndConflictingVersionsAreRefused) {
  Signer s;
  CampaignAuthority a(s.trusted(), "bike-7");
  auto c = test::base_campaign();
  c.set_version(5);
  ASSERT_TRUE(offer(a, s.sign(c)).accepted());
  c.set_version(4);
  EXPECT_EQ(offer(a, s.sign(c)).reason, CampaignRefusal::kNotNewer);
  c.set_version(5);
  c.set_priority(1);
  EXPECT_EQ(offer(a, s.sign(c)).reason, CampaignRefusal::kVersionConflict);
  c.set_version(6);
  EXPECT_TRUE(offer(a, s.sign(c)).accepted());
  EXPECT_EQ(a.in_force().at("cells-hot").compiled.priority, 1);
}

TEST(CampaignAuthority, OverBudgetCampaignsAreRefused) {
  Signer s;
  CampaignLimits limits;
  limits.total_disk_budget = 3u << 20;
  limits.max_campaigns = 3;
  CampaignAuthority a(s.trusted(), "bike-7", {}, limits);
  for (int i = 0; i < 2; ++i) {
    auto c = test::base_campaign();
    c.set_id("c" + std::to_string(i));
    ASSERT_TRUE(offer(a, s.sign(c)).accepted());
  }
  auto big = test::base_campaign();
  big.set_id("big");
  big.set_disk_budget_bytes(2u << 20);
  const auto v = offer(a, s.sign(big));
  EXPECT_EQ(v.reason, CampaignRefusal::kOverBudget);
  EXPECT_EQ(v.detail.rfind("disk_budget_bytes:", 0), 0u);
  big.set_disk_budget_bytes(1u << 20);
  EXPECT_TRUE(offer(a, s.sign(big)).accepted());
  big.set_id("fourth");
  EXPECT_EQ(offer(a, s.sign(big)).reason, CampaignRefusal::kOverBudget);
  // Past their end they leave.
  EXPECT_EQ(a.expire(kDay0 + 11 * 86'400 * kSecond).size(), 3u);
  EXPECT_TRUE(a.in_force().empty());
}

}  // namespace
}  // namespace fleetgw::campaign
