// Campaign samples (issue 29): one Envelope.campaign (fleetgw.v1.CampaignSamples, one outbox
// record of the gateway) becomes one row per sample in `campaign_samples` (migration 7,
// migrations_v7_campaigns.cc), keyed by (vehicle_id, store_id, sequence, sample_index) so a
// record delivered twice is written once.
//
// Contract: campaign_rows() rejects (code, detail naming the field) a record without a campaign
// id or with more than kMaxCampaignSamples samples, a sample whose signal index is outside the
// record's signal names, a text over kMaxText bytes. Values stay in the wire's integer form
// (value_e6); the table derives `value` from it.
#pragma once

#include <optional>

#include "backend/ingest/envelope_rows.h"

namespace fleetgw::v1 {
class Envelope;
}  // namespace fleetgw::v1

namespace fleetgw::ingest {

// A gateway cuts a record at 1024 samples; 10 times that is surely not one of ours.
constexpr std::size_t kMaxCampaignSamples = 10240;

extern const TableSpec kCampaignSamplesTable;

std::optional<Reject> campaign_rows(const v1::Envelope& e, Decoded& d);

// Migration 7's SQL (migrations_v7_campaigns.cc).
std::string_view migration_v7_sql();

}  // namespace fleetgw::ingest
