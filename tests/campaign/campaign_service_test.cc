// The campaigns of one gateway over its real SQLite store (issue 29): an accepted campaign is
// stored at once and runs again after a restart with no broker; its records enter the outbox at
// the campaign priority, behind telemetry, faults and alarms; status() shows its bounds.
#include <gtest/gtest.h>

#include "campaign_test_util.h"
#include "gateway/campaign/campaign_service.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kSecond;

storage::StoreOptions store_options(const testing::TempDir& dir) {
  storage::StoreOptions o;
  o.path = (dir.path() / "fleetgw.db").string();
  return o;
}

struct Gateway {
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  CampaignServiceConfig config() const {
    CampaignServiceConfig c;
    c.trusted_keys = {{"eng", key.public_key().base64()}};
    c.vehicle_id = "bike-1";
    c.fleet_topic = "fleet/v1/campaigns";
    c.vehicle_topic = "fleet/v1/bike-1/campaigns";
    return c;
  }
};

TEST(CampaignService, AnAcceptedCampaignIsStoredAndRunsAfterARestartOffline) {
  testing::TempDir dir;
  Gateway gw;
  const std::string payload = sign_campaign(test::base_campaign(), gw.key, "eng");
  {
    storage::Store store(store_options(dir));
    CampaignService service(gw.config(), store);
    EXPECT_FALSE(service.handles("fleet/v1/zones"));
    ASSERT_TRUE(service.handles("fleet/v1/campaigns"));
    const auto v = service.on_payload("fleet/v1/campaigns", payload, 0, kDay0, kDay0);
    ASSERT_TRUE(v.accepted()) << v.detail;
  }
  storage::Store store(store_options(dir));
  CampaignService service(gw.config(), store);
  service.restore(kDay0 + kSecond, kDay0 + kSecond);
  ASSERT_EQ(service.size(), 1u);
  // It runs on the bus without any broker: a sample, recorded at its end.
  const auto& cat = motinova::Catalogue::standard();
  const motinova::DecodeOptions options;
  const auto frame = motinova::MessageWriter(*cat.find("mc_status", 0x710), options)
                         .value("motor_temp_c", 55)
                         .frame();
  motinova::DecodedMessage m;
  motinova::decode(frame, cat, options, m);
  service.on_message(kDay0 + 2 * kSecond, m);
  service.tick(kDay0 + 2 * kSecond, kDay0 + 40 * kSecond);  // 30 s after its first sample
  const auto messages = service.take_messages();
  ASSERT_EQ(messages.size(), 1u);
  EXPECT_EQ(messages[0].kind, storage::OutboxKind::kCampaign);
  // Its priority 5 among campaigns: outbox priority 6 + 5, below every record of the product.
  EXPECT_EQ(messages[0].priority, static_cast<int>(storage::OutboxPriority::kCampaign) + 5);
  const auto status = service.status(kDay0 + 40 * kSecond);
  EXPECT_EQ(status["in_force"], 1);
  EXPECT_EQ(status["bus_now_us"], (kDay0 + 40 * kSecond).count());  // the clock it was judged on
  EXPECT_EQ(status["campaigns"][0]["state"], "running");
  EXPECT_EQ(status["campaigns"][0]["max_bytes_per_hour"], 3600u * 27u);

  // Into the outbox behind telemetry (and so behind faults and alarms).
  storage::Batch batch;
  batch.now_us = (kDay0 + 40 * kSecond).count();
  batch.messages.push_back(messages[0]);
  batch.messages.push_back({storage::OutboxKind::kInfo, storage::kLowestPriority, {1, 2}});
  ASSERT_TRUE(store.write(batch).ok());
  const auto peeked = store.peek_outbox(10, 1 << 20);
  ASSERT_EQ(peeked.size(), 2u);
  EXPECT_EQ(peeked[0].kind, storage::OutboxKind::kInfo);
  EXPECT_EQ(peeked[1].kind, storage::OutboxKind::kCampaign);
  // Priority 6 is the campaigns' alone.
  storage::Batch wrong;
  wrong.now_us = batch.now_us;
  wrong.messages.push_back({storage::OutboxKind::kInfo, 6, {1}});
  EXPECT_FALSE(store.write(wrong).ok());
}

TEST(CampaignService, ATamperedStoredCampaignIsRefusedAtRestartAndDropped) {
  testing::TempDir dir;
  Gateway gw;
  {
    storage::Store store(store_options(dir));
    CampaignService service(gw.config(), store);
    ASSERT_TRUE(service
                    .on_payload("fleet/v1/campaigns",
                                sign_campaign(test::base_campaign(), gw.key, "eng"), 0, kDay0,
                                kDay0)
                    .accepted());
    // Someone edits the stored row: still base64, no longer what was signed.
    storage::Batch b;
    b.meta.emplace_back("campaign.cells-hot", "AAAA");
    ASSERT_TRUE(store.write(b).ok());
  }
  storage::Store store(store_options(dir));
  CampaignService service(gw.config(), store);
  service.restore(kDay0, kDay0);
  EXPECT_EQ(service.size(), 0u);
  EXPECT_EQ(store.meta("campaign.index").value_or("?"), "");
}

TEST(CampaignService, RefusalsAreCountedWithTheirReason) {
  testing::TempDir dir;
  Gateway gw;
  storage::Store store(store_options(dir));
  CampaignService service(gw.config(), store);
  auto fleet = test::base_campaign();
  // On the vehicle's own topic a campaign must name the vehicle.
  auto v = service.on_payload("fleet/v1/bike-1/campaigns", sign_campaign(fleet, gw.key, "eng"), 0,
                              kDay0, kDay0);
  EXPECT_EQ(v.reason, CampaignRefusal::kNotForThisVehicle);
  v = service.on_payload("fleet/v1/campaigns", "", 70'000, kDay0, kDay0);
  EXPECT_EQ(v.reason, CampaignRefusal::kTooLarge);
  const auto status = service.status(kDay0);
  EXPECT_EQ(status["refused"], 2);
  EXPECT_EQ(status["last_refusal"]["reason"], "too_large");
}

}  // namespace
}  // namespace fleetgw::campaign
