// The ingest's rows of a campaign record (issue 29): one campaign_samples row per sample, with
// the sample's absolute time, its signal's name and the record's key; malformed records are
// rejected naming the field.
#include <gtest/gtest.h>

#include "backend/ingest/campaign_rows.h"
#include "backend/ingest/envelope_rows.h"
#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::ingest {
namespace {

v1::Envelope campaign_envelope() {
  v1::Envelope e;
  e.set_vehicle_id("bike-3");
  e.set_store_id("store-a");
  e.set_sequence(41);
  e.set_created_at_us(1'000'000);
  e.set_gateway_fw_version("0.1.0");
  auto* c = e.mutable_campaign();
  c->set_campaign_id("hot-pack");
  c->set_campaign_version(3);
  c->add_signals("bms.cells.cells_mv[0]");
  c->add_signals("mc.device_info.fw");
  c->set_base_us(5'000'000);
  c->set_trigger_at_us(5'100'000);
  auto* a = c->add_samples();
  a->set_signal(0);
  a->set_offset_us(0);
  a->set_value_e6(3'301'000'000);
  auto* b = c->add_samples();
  b->set_signal(1);
  b->set_offset_us(250'000);
  b->set_text("MC-1.2");
  return e;
}

TEST(CampaignRows, OneRowPerSampleKeyedByTheRecord) {
  const auto r = decode_message("fleet/v1", "fleet/v1/bike-3/campaign",
                                campaign_envelope().SerializeAsString());
  ASSERT_TRUE(std::holds_alternative<Decoded>(r)) << std::get<Reject>(r).detail;
  const auto& d = std::get<Decoded>(r);
  ASSERT_EQ(d.rows.size(), 1u);
  EXPECT_EQ(d.rows[0].table->table, "campaign_samples");
  ASSERT_EQ(d.rows[0].rows(), 2u);
  EXPECT_EQ(d.ranges, (std::vector<SequenceRange>{{41, 41}}));
  const auto& v = d.rows[0].values();
  const auto cols = static_cast<std::size_t>(d.rows[0].table->column_count);
  // vehicle, store, sequence, sample_index, ..., signal, sampled_at_us, value_e6, text.
  EXPECT_EQ(*v[0], "bike-3");
  EXPECT_EQ(*v[2], "41");
  EXPECT_EQ(*v[3], "0");
  EXPECT_EQ(*v[8], "bms.cells.cells_mv[0]");
  EXPECT_EQ(*v[9], "5000000");
  EXPECT_EQ(*v[10], "3301000000");
  EXPECT_FALSE(v[11].has_value());
  EXPECT_EQ(*v[cols + 3], "1");
  EXPECT_EQ(*v[cols + 8], "mc.device_info.fw");
  EXPECT_EQ(*v[cols + 9], "5250000");
  EXPECT_FALSE(v[cols + 10].has_value());
  EXPECT_EQ(*v[cols + 11], "MC-1.2");
  EXPECT_EQ(*v[cols + 13], "5100000");
}

TEST(CampaignRows, MalformedRecordsAreRejected) {
  auto e = campaign_envelope();
  e.mutable_campaign()->mutable_samples(1)->set_signal(2);
  auto r = decode_message("fleet/v1", "fleet/v1/bike-3/campaign", e.SerializeAsString());
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).detail, "campaign.samples[1].signal 2 is not one of its 2 signals");
  e = campaign_envelope();
  e.mutable_campaign()->clear_campaign_id();
  r = decode_message("fleet/v1", "fleet/v1/bike-3/campaign", e.SerializeAsString());
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).code, "bad_campaign_samples");
  // On another leaf: the body names its own.
  r = decode_message("fleet/v1", "fleet/v1/bike-3/telemetry",
                     campaign_envelope().SerializeAsString());
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).code, "wrong_leaf");
}

}  // namespace
}  // namespace fleetgw::ingest
