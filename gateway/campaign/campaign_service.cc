#include "gateway/campaign/campaign_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <sstream>

#include "fleetgw/v1/campaign.pb.h"

#include "gateway/command/base64.h"

namespace fleetgw::campaign {
namespace {

constexpr const char* kIndexKey = "campaign.index";

std::span<const std::uint8_t> service_bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

}  // namespace

CampaignService::CampaignService(CampaignServiceConfig config, storage::Store& store)
    : config_(std::move(config)),
      store_(store),
      authority_(config_.trusted_keys, config_.vehicle_id, config_.groups, config_.limits) {
  authority_.set_delegated_check(config_.delegated_check);  // before restore(): issue 28
}

bool CampaignService::handles(std::string_view topic) const {
  return topic == config_.fleet_topic || topic == config_.vehicle_topic;
}

void CampaignService::restore(Micros wall_now, Micros bus_now) {
  const auto index = store_.meta(kIndexKey);
  if (!index) return;
  std::istringstream ids(*index);
  std::string id;
  while (ids >> id) {
    const auto text = store_.meta("campaign." + id);
    const auto payload = text ? command::decode_base64(*text) : std::nullopt;
    if (!payload) {
      spdlog::warn("campaign: stored campaign '{}' is unreadable; dropped", id);
      continue;
    }
    const std::string bytes(payload->begin(), payload->end());
    // Judged as on the fleet topic: a stored per-vehicle campaign names this vehicle anyway.
    auto v = authority_.offer(bytes, wall_now, CampaignTopic::kFleet);
    if (!v.accepted()) {
      spdlog::warn("campaign: stored campaign '{}' refused ({}): {}", id,
                   campaign_refusal_name(v.reason), v.detail);
      continue;
    }
    engine_.put(authority_.in_force().at(v.id).compiled, bus_now);
    spdlog::info("campaign: '{}' restored: {}", v.id, v.detail);
  }
  persist();  // drops what was refused
  count_stored_records();
}

void CampaignService::count_stored_records() {
  std::map<std::string, std::uint64_t, std::less<>> bytes;
  v1::CampaignSamples rec;
  store_.visit_outbox(storage::OutboxKind::kCampaign, [&](const storage::OutboxRow& e) {
    // Only the id is needed; a payload that does not parse is counted nowhere (it still leaves
    // the store with the outbox).
    if (rec.ParseFromArray(e.payload.data(), static_cast<int>(e.payload.size()))) {
      bytes[rec.campaign_id()] += e.payload.size();
    }
  });
  for (const auto& [id, n] : bytes) engine_.set_bytes_in_store(id, n);
}

int CampaignService::outbox_priority(int campaign_priority) {
  return static_cast<int>(storage::OutboxPriority::kCampaign) +
         std::clamp(campaign_priority, 0,
                    storage::kLowestCampaignPriority -
                        static_cast<int>(storage::OutboxPriority::kCampaign));
}

void CampaignService::store_holds(std::span<const storage::OutboxDepth> depth) {
  for (int p = 0; p <= kMaxPriority; ++p) {
    std::uint64_t bytes = 0;
    for (const auto& d : depth) {
      if (d.priority == outbox_priority(p)) bytes = d.payload_bytes;
    }
    engine_.store_holds_at(p, bytes);
  }
}

CampaignVerdict CampaignService::on_payload(std::string_view topic, std::string_view payload,
                                            std::size_t oversized, Micros wall_now,
                                            Micros bus_now) {
  ++offered_;
  expire(wall_now, bus_now);
  const CampaignTopic from =
      topic == config_.vehicle_topic ? CampaignTopic::kVehicle : CampaignTopic::kFleet;
  CampaignVerdict v;
  if (oversized > 0) {
    v.reason = CampaignRefusal::kTooLarge;
    v.detail = std::to_string(oversized) + " bytes, over the topic's limit";
  } else if (payload.empty()) {
    // A retained message cleared by the operator: nothing to judge (campaigns end at their end).
    v.outcome = CampaignOutcome::kAlreadyInForce;
    v.detail = "empty retained message";
    return v;
  } else {
    v = authority_.offer(service_bytes(payload), wall_now, from);
  }
  if (v.accepted()) {
    ++accepted_;
    if (const Status stored = persist(); !stored.ok()) {
      spdlog::error("campaign: '{}' not stored: {}", v.id, stored.message);
    }
    engine_.put(authority_.in_force().at(v.id).compiled, bus_now);
    spdlog::info("campaign: '{}' accepted: {}", v.id, v.detail);
  } else if (v.outcome == CampaignOutcome::kRefused) {
    ++refused_;
    last_refusal_ = v;
    const std::string key = std::string(campaign_refusal_name(v.reason)) + v.id;
    if (key != last_logged_) {
      spdlog::warn("campaign: refused ({}) on {}: {}", campaign_refusal_name(v.reason), topic,
                   v.detail);
      last_logged_ = key;
    }
  }
  return v;
}

void CampaignService::expire(Micros wall_now, Micros bus_now) {
  const auto gone = authority_.expire(wall_now);
  if (gone.empty()) return;
  for (const auto& id : gone) {
    engine_.remove(id, bus_now);
    spdlog::info("campaign: '{}' ended", id);
  }
  persist();
}

void CampaignService::tick(Micros wall_now, Micros bus_now) {
  engine_.tick(bus_now);
  expire(wall_now, bus_now);
}

std::vector<storage::UplinkMessage> CampaignService::take_messages() {
  std::vector<storage::UplinkMessage> out;
  for (auto& r : engine_.take_records()) {
    out.push_back({storage::OutboxKind::kCampaign, outbox_priority(r.priority),
                   storage::Bytes(r.payload.begin(), r.payload.end())});
  }
  return out;
}

Status CampaignService::persist() {
  storage::Batch batch;
  std::string index;
  for (const auto& [id, held] : authority_.in_force()) {
    index += index.empty() ? id : " " + id;
    batch.meta.emplace_back("campaign." + id, command::encode_base64(service_bytes(held.payload)));
  }
  batch.meta.emplace_back(kIndexKey, index);
  return store_.write(batch).status();
}

nlohmann::json CampaignService::status(Micros bus_now) const {
  nlohmann::json campaigns = nlohmann::json::array();
  for (const auto& v : engine_.view(bus_now)) {
    const CompiledCampaign& c = *v.campaign;
    campaigns.push_back({{"id", c.id},
                         {"version", c.version},
                         {"state", run_state_name(v.state)},
                         {"signals", c.signals.size()},
                         {"trigger", trigger_name(c.trigger)},
                         {"sampling", sampling_name(c.sampling)},
                         {"priority", c.priority},
                         {"max_bytes_per_hour", c.cost.max_bytes_per_hour},
                         {"ring_samples", c.cost.ring_samples},
                         {"disk_budget_bytes", c.disk_budget_bytes},
                         {"bytes_in_store", v.counters.bytes_in_store},
                         {"samples", v.counters.samples},
                         {"dropped", v.counters.dropped},
                         {"records", v.counters.records},
                         {"events", v.counters.events}});
  }
  nlohmann::json last = nullptr;
  if (last_refusal_) {
    last = {{"reason", campaign_refusal_name(last_refusal_->reason)},
            {"detail", last_refusal_->detail},
            {"id", last_refusal_->id}};
  }
  // bus_now_us: the bike's clock the windows are judged on, which a simulated or slipping bus
  // keeps apart from the wall clock (why a window has or has not opened yet).
  return {{"in_force", engine_.size()},   {"offered", offered_},  {"accepted", accepted_},
          {"refused", refused_},          {"last_refusal", last}, {"campaigns", campaigns},
          {"bus_now_us", bus_now.count()}};
}

}  // namespace fleetgw::campaign
