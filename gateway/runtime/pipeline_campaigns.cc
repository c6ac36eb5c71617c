// Collection campaigns in the pipeline (issue 29; docs/campaigns.md): the CampaignService built
// with the commands' trusted keys (and their roots' delegations, issue 28) and the vehicle's id and
// groups, its stored campaigns restored at start-up (they run offline from the first frame), its
// topics subscribed with the zone bundles' (Uplink::take_zone_bundles hands both; settle() routes
// by topic), fed by the core after the recorder (CampaignFeed), its records queued through the
// recorder.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/runtime/campaign_feed.h"
#include "gateway/runtime/pipeline.h"
#include "gateway/uplink/topics.h"

namespace fleetgw::runtime {

void Pipeline::add_campaign_topics(const config::Config& config,
                                   uplink::UplinkConfig& uplink_config) {
  // Nothing could be verified without a trusted key or a root (issue 28's delegated keys).
  if (config.command.trusted_keys.empty() && config.command.root_keys.empty()) return;
  const uplink::Topics topics(config.mqtt.topic_prefix, config.vehicle.id);
  uplink_config.zone_topics.push_back(topics.fleet_campaigns);
  uplink_config.zone_topics.push_back(topics.campaigns);
}

void Pipeline::start_campaigns(const config::Config& config) {
  if (config.command.trusted_keys.empty() && config.command.root_keys.empty()) return;
  const uplink::Topics topics(config.mqtt.topic_prefix, config.vehicle.id);
  campaign::CampaignServiceConfig c;
  c.trusted_keys = config.command.trusted_keys;
  // Issue 28: a campaign signed under a root's delegation with the action "campaign"; set
  // before restore() so stored campaigns of delegated keys are judged again, not dropped.
  if (!config.command.root_keys.empty()) {
    c.delegated_check = commands_->delegated_document_check("campaign");
  }
  c.vehicle_id = config.vehicle.id;
  c.groups = config.vehicle.groups;
  c.fleet_topic = topics.fleet_campaigns;
  c.vehicle_topic = topics.campaigns;
  // Inside the store's budget: the campaigns together hold at most a quarter of it, so their
  // records (evicted only after telemetry) cannot crowd out the records the reserve protects.
  if (const auto budget = store_.effective_budget(); budget > 0) {
    c.limits.total_disk_budget = std::min(c.limits.total_disk_budget, budget / 4);
  }
  campaigns_ = std::make_unique<campaign::CampaignService>(std::move(c), store_);
  campaigns_->restore(start_, start_);  // the bike's clock: a replay judges by its own
  if (campaigns_->size() > 0) spdlog::info("campaign: {} in force", campaigns_->size());
  campaign_feed_ = std::make_unique<CampaignFeed>(*campaigns_, *recorder_, store_, env_);
  core_.add_listener(*campaign_feed_);
}

std::optional<nlohmann::json> Pipeline::campaign_status() const {
  if (!campaigns_) return std::nullopt;
  return campaigns_->status(bus_now());
}

}  // namespace fleetgw::runtime
