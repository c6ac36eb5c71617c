// Pipeline: the wiring of the geofence (issue 14). The policy lives in the ZonesStage
// (zones_stage.h); here it is built from [geofence] with the parts other stages own (the
// command service's speed authority and delegated-document check), connected to its inputs
// (the command service's lock and unlock guards, the lock tracker's bike locks; positions and
// bundles come through route_gnss() and route_uplink()), and its outputs are moved: zone events
// to the speed authority (which names the slow zone behind a limit in an operator's result), the
// campaigns (issue 29) and the recorder (stored in zone_events and queued as Envelope.zone,
// topic .../zone, in the same transaction discipline as alarms); the outside_operating_area
// alarm to the recorder and the vehicle state; an MC write (speed limit, assist level) started
// through the command service's own-action path, one at a time, its outcome back to the stage.
#include <spdlog/spdlog.h>

#include "gateway/common/untrusted_text.h"
#include "gateway/runtime/pipeline.h"

namespace fleetgw::runtime {

void Pipeline::start_zones(const config::Config& config) {
  if (!config.geofence.enabled) return;
  ZonesStageConfig zc = make_zones_stage_config(config);
  // One authority for the speed limit (issue 24): the zones' demand and the operator's cap
  // (from speed-limit commands) meet in the command service's, which outlives the stage.
  auto& speed = commands_->speed_authority();
  speed.set_own_limit(config.geofence.own_limit_kmh);
  zc.controller.enforcer.speed = &speed;
  // Issue 28: a bundle signed under a root's delegation with the action "zones".
  if (!config.command.root_keys.empty()) {
    zc.controller.delegated_check = commands_->delegated_document_check("zones");
  }
  zones_stage_ = std::make_unique<ZonesStage>(std::move(zc), env_);
  // Lock commands ask the no-parking zones, unlock commands the no-start zones (issue 27), at
  // the fix current now; the zone event concluded is stored through the route.
  commands_->set_lock_guard([this](bool ride_ending, Micros) {
    auto refusal = zones_stage_->judge_lock(ride_ending);
    if (!zones_stage_->records.empty()) request_settle();
    return refusal;
  });
  commands_->set_unlock_guard([this](bool ride_starting, Micros) {
    auto refusal = zones_stage_->judge_unlock(ride_starting);
    if (!zones_stage_->records.empty()) request_settle();
    return refusal;
  });
  // A lock made on the bike is only noted (the recorder is mid-message); the stage judges it.
  recorder_->trackers().set_lock_observer([this](const storage::LockEventRow& ev, int new_raw) {
    zones_stage_->on_lock_event(ev.kind, new_raw, ev.cause);
    request_settle();
  });
  zones_stage_->restore();
  route_zones();  // what the restored bundle concluded goes out with the first flush
}

bool Pipeline::route_zones() {
  ZonesStage& z = *zones_stage_;
  for (auto& r : std::exchange(z.records, {})) {
    commands_->speed_authority().on_zone_event(r.event,
                                               common::untrusted_excerpt(r.event.zone_name, 64));
    if (campaigns_ && (r.event.transition == geofence::Transition::kEnter ||
                       r.event.transition == geofence::Transition::kExit)) {
      campaigns_->on_zone(r.event.zone_id, r.event.zone_name,
                          r.event.transition == geofence::Transition::kEnter);
    }
    recorder_->record_zone_event(std::move(r.row), std::move(r.payload));
  }
  for (auto& a : std::exchange(z.alarms, {})) {
    recorder_->record_alarm(std::move(a.row), std::move(a.payload));
  }
  state_stage_->set_outside_operating_area(z.outside_operating_area());
  if (z.take_state_touched()) state_stage_->touch();
  if (z.mc_write) {
    auto write = std::move(*z.mc_write);
    z.mc_write.reset();
    start_zone_write(std::move(write));
  }
  return false;  // the recorder and the vehicle state run later in this round
}

void Pipeline::start_zone_write(ZonesStage::McWriteRequest write) {
  // The write acts on the bus as it is now, not as of the last batch.
  if (bus_.sim) bus_.sim->flush();
  auto done = [this, token = std::weak_ptr<int>(alive_)](bool ok, std::string reason, Micros) {
    if (token.expired()) return;
    zones_stage_->on_write_done(ok, reason);
    request_settle();
  };
  if (auto refused = commands_->start_own_mc_action(write.request, bus_now(), std::move(done))) {
    zones_stage_->on_write_refused(
        fmt::format("{}: {}", command::reject_reason_name(refused->reason), refused->detail));
    return;
  }
  zones_stage_->on_write_started();
}

std::optional<GeofenceStatus> Pipeline::geofence_status() const {
  if (!zones_stage_) return std::nullopt;
  const ZonesStage& z = *zones_stage_;
  GeofenceStatus g;
  if (const auto& f = z.controller().authority().in_force()) {
    g.version = f->zones->version;
    g.zones = f->zones->zones.size();
    g.vertices = f->zones->vertices;
    g.key_id = f->key_id;
    g.issued_at_us = f->zones->issued_at.count();
  }
  g.bundle_file = z.bundle_file();
  g.topics = z.topics();
  g.counters = z.controller().counters();
  if (uplink_) g.dropped = uplink_->stats().zone_bundles_dropped;
  g.last_refusal_topic = z.last_refusal_topic();
  g.outside_operating_area = z.outside_operating_area();
  return g;
}

}  // namespace fleetgw::runtime
