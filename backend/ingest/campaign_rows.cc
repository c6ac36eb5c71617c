#include "backend/ingest/campaign_rows.h"

#include "backend/ingest/record_rows.h"
#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::ingest {

const TableSpec kCampaignSamplesTable{
    "campaign_samples",
    "vehicle_id, store_id, sequence, sample_index, created_at_us, gateway_fw_version, "
    "campaign_id, campaign_version, signal, sampled_at_us, value_e6, text, invalid, "
    "trigger_at_us",
    14, "ON CONFLICT DO NOTHING"};

std::optional<Reject> campaign_rows(const v1::Envelope& e, Decoded& d) {
  const v1::CampaignSamples& c = e.campaign();
  if (c.campaign_id().empty()) {
    return Reject{"bad_campaign_samples", "campaign.campaign_id is empty"};
  }
  if (static_cast<std::size_t>(c.samples_size()) > kMaxCampaignSamples) {
    return Reject{"too_many_samples", fmt::format("campaign record of {} samples (at most {})",
                                                  c.samples_size(), kMaxCampaignSamples)};
  }
  RowSet& rows =
      rows::new_rows(d, kCampaignSamplesTable, static_cast<std::size_t>(c.samples_size()));
  rows::RowBuilder b(rows);
  for (int i = 0; i < c.samples_size(); ++i) {
    const v1::CampaignSample& s = c.samples(i);
    if (static_cast<int>(s.signal()) >= c.signals_size()) {
      return Reject{"bad_campaign_samples",
                    fmt::format("campaign.samples[{}].signal {} is not one of its {} signals", i,
                                s.signal(), c.signals_size())};
    }
    b.text("vehicle_id", e.vehicle_id());
    b.text("store_id", e.store_id());
    b.u64("sequence", e.sequence());
    b.i64(i);
    b.i64(e.created_at_us());
    b.text("gateway_fw_version", e.gateway_fw_version());
    b.text("campaign.campaign_id", c.campaign_id());
    b.u64("campaign.campaign_version", c.campaign_version());
    b.text("campaign.signals", c.signals(static_cast<int>(s.signal())));
    if (s.offset_us() > static_cast<std::uint64_t>(INT32_MAX) * 1000) {  // ~25 days
      b.fail("value_out_of_range", fmt::format("campaign.samples[{}].offset_us too large", i));
    }
    b.i64(c.base_us() + static_cast<std::int64_t>(s.offset_us()));
    s.text().empty() ? b.i64(s.value_e6()) : b.null();
    s.text().empty() ? b.null() : b.text("campaign.samples.text", s.text());
    b.boolean(s.invalid());
    b.opt_i64(c.trigger_at_us() != 0, c.trigger_at_us());
  }
  if (b.error) return *b.error;
  d.records += 1;
  return std::nullopt;
}

}  // namespace fleetgw::ingest
