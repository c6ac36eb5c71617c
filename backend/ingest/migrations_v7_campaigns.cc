// Migration 7 (issue 29; campaign_rows.h): the samples of collection campaigns. Kept apart from
// migrations.cc, after migrations_v4.cc's example.
#include "backend/ingest/campaign_rows.h"

namespace fleetgw::ingest {

std::string_view migration_v7_sql() {
  return R"sql(
-- Issue 29: the samples of collection campaigns, one row per sample of an Envelope.campaign
-- record. value_e6 is the wire's value times 10^6; `value` is the same in the signal's unit
-- (`fleetgw signals`). Text signals carry `text` instead.
CREATE TABLE campaign_samples (
  vehicle_id text NOT NULL, store_id text NOT NULL, sequence bigint NOT NULL,
  sample_index integer NOT NULL,
  created_at_us bigint NOT NULL, committed_at_us bigint NOT NULL DEFAULT fleet_now_us(),
  gateway_fw_version text NOT NULL,
  campaign_id text NOT NULL, campaign_version bigint NOT NULL, signal text NOT NULL,
  sampled_at_us bigint NOT NULL, value_e6 bigint, text text, invalid boolean NOT NULL,
  trigger_at_us bigint,
  value double precision GENERATED ALWAYS AS (value_e6 / 1e6) STORED,
  PRIMARY KEY (vehicle_id, store_id, sequence, sample_index));
CREATE INDEX campaign_samples_by_campaign
  ON campaign_samples (campaign_id, campaign_version, signal, sampled_at_us);
CREATE INDEX campaign_samples_by_vehicle ON campaign_samples (vehicle_id, sampled_at_us);
)sql";
}

}  // namespace fleetgw::ingest
