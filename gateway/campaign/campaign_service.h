// CampaignService: the campaigns of one gateway as the runtime drives them -- the authority
// (which signed campaigns are in force), their persistence in the store, the engine on the
// decoded messages, and the records for the outbox. The runtime's wiring is: restore() at
// start-up, on_payload() for each message of the campaign topics, on_message()/tick() from the
// core, take_messages() into the recorder, store_holds() with the outbox depth of the campaign
// priority, status() for `fleetgw status`. No MQTT, no clock.
//
// Contract:
//  * Persistence: each accepted campaign is written at once to the store's meta table
//    ("campaign.<id>" = the SignedCampaign in base64, "campaign.index" = the ids), in its own
//    transaction, so it runs after a restart with the broker down; restore() offers each stored
//    one again (re-verified: a tampered row or a key no longer trusted is refused and dropped).
//    Campaigns past their end are dropped from the store at the next on_payload() or tick().
//  * Results: storage::UplinkMessage of kind kCampaign at OutboxPriority::kCampaign + the
//    campaign's priority (6..15, below telemetry): through the same outbox, exactly once, never
//    ahead of a fault or alarm; a more urgent campaign's records first.
//  * Disk budget across restarts: restore() counts each campaign's records still in the outbox
//    (their payloads name the campaign), so a restarted bike does not grant a fresh budget.
//  * Refusals are logged once per distinct reason and counted; the latest is in status().
//  * `wall_now` is the clock a campaign's start and end (expired, ended) are judged on; the
//    pipeline passes the bus clock, the one its windows run on (the system clock on a bike, the
//    log's in a replay).
#pragma once

#include <nlohmann/json.hpp>

#include <map>
#include <span>
#include <string>
#include <vector>

#include "gateway/campaign/campaign_authority.h"
#include "gateway/campaign/campaign_engine.h"
#include "storage/store.h"

namespace fleetgw::campaign {

struct CampaignServiceConfig {
  std::map<std::string, std::string> trusted_keys;  // [command.trusted_keys]
  std::string vehicle_id;
  std::vector<std::string> groups;
  std::string fleet_topic;    // <prefix>/campaigns
  std::string vehicle_topic;  // <prefix>/<vehicle>/campaigns
  CampaignLimits limits;
  // Issue 28: campaigns signed under a root's delegation with the action "campaign" (the
  // command service's check); unset: only trusted keys.
  CampaignAuthority::DelegatedCheck delegated_check;
};

class CampaignService {
 public:
  CampaignService(CampaignServiceConfig config, storage::Store& store);

  void restore(Micros wall_now, Micros bus_now);
  bool handles(std::string_view topic) const;
  // A payload of one of the campaign topics; `oversized` > 0: refused unread as too_large.
  CampaignVerdict on_payload(std::string_view topic, std::string_view payload,
                             std::size_t oversized, Micros wall_now, Micros bus_now);
  void on_message(Micros bus_now, const motinova::DecodedMessage& message) {
    engine_.on_message(bus_now, message);
  }
  // The geofence's zone events (enter: inside = true, exit: false), for zone triggers.
  void on_zone(std::string_view zone_id, std::string_view zone_name, bool inside) {
    engine_.on_zone(zone_id, zone_name, inside);
  }
  void tick(Micros wall_now, Micros bus_now);
  std::vector<storage::UplinkMessage> take_messages();
  // The store's outbox depth (Store::outbox_depth()): each campaign priority's depth scales the
  // bytes in store of that priority's campaigns (acknowledged or evicted records).
  void store_holds(std::span<const storage::OutboxDepth> depth);
  // The outbox priority of a campaign's records: OutboxPriority::kCampaign + its priority
  // (6..15), so a more urgent campaign's records go first and are evicted last.
  static int outbox_priority(int campaign_priority);
  std::size_t size() const { return engine_.size(); }
  // {"in_force": n, "offered", "accepted", "refused", "last_refusal": {...} | null,
  //  "campaigns": [{id, version, state, signals, trigger, sampling, priority,
  //  max_bytes_per_hour, ring_samples, disk_budget_bytes, bytes_in_store, samples, dropped,
  //  records, events}]}
  nlohmann::json status(Micros bus_now) const;

 private:
  // Stores the campaigns in force (meta table); the store's Status when that failed.
  Status persist();
  void count_stored_records();
  void expire(Micros wall_now, Micros bus_now);

  CampaignServiceConfig config_;
  storage::Store& store_;
  CampaignAuthority authority_;
  CampaignEngine engine_;
  std::uint64_t offered_ = 0, accepted_ = 0, refused_ = 0;
  std::optional<CampaignVerdict> last_refusal_;
  std::string last_logged_;
};

}  // namespace fleetgw::campaign
