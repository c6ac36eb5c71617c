// Geofences in the pipeline (issue 14): the ZoneController built from [geofence] with the
// commands' trusted keys, its stored bundle restored at start-up (zones apply offline from the
// first fix), every GNSS change handed to it, and its MC writes (speed limit, assist level)
// started through the command service's own-action path, one at a time, confirmed from the bus.
// Every zone event is logged, stored (zone_events) and queued for the uplink (Envelope.zone,
// topic .../zone) through the recorder, in the same transaction discipline as alarms. Leaving
// every operating area raises the outside_operating_area Alarm, re-entering one clears it. Lock
// commands ask the no-parking zones first (CommandService::set_lock_guard): reported, or refused
// as no_parking_zone when configured; a lock made on the bike (a lock event from the bus) is
// judged after the fact and reported; unlock commands ask the no-start zones (issue 27) and
// are refused as no_start_zone. Bundles come from the stored file at start-up and from the
// retained zone topics (Uplink::take_zone_bundles), judged and enforced here, on the loop.
#include <spdlog/spdlog.h>

#include <cmath>

#include "gateway/common/untrusted_text.h"
#include "gateway/domain/alarm_payload.h"
#include "gateway/geofence/zone_payload.h"
#include "gateway/runtime/clock_units.h"
#include "gateway/runtime/pipeline.h"

namespace fleetgw::runtime {

namespace {

storage::ZoneEventRow zone_record(const geofence::ZoneEvent& e) {
  storage::ZoneEventRow r;
  r.ts_us = e.at.count();
  r.zone_id = e.zone_id;
  r.zone_name = e.zone_name;
  r.kind = std::string(geofence::zone_kind_name(e.kind));
  r.transition = std::string(geofence::transition_name(e.transition));
  r.bundle_version = e.bundle_version;
  if (e.position) {
    r.lat_deg = e.position->lat_deg;
    r.lon_deg = e.position->lon_deg;
  }
  // Slow zones, and GBFS rules zones with a limit (issue 27).
  if (e.speed_limit_kmh > 0) r.speed_limit_kmh = e.speed_limit_kmh;
  return r;
}

// The enforcer's ladder, lowest first: the configured names (`[protocol] assist_names`, U7) of
// the plain levels 0 (off) to 4 (turbo). Other values (walk, the "2" variants) are not on it, so
// the enforcer counts them as the highest and lowers them in a fade.
std::vector<std::string> enforcer_assist_levels(const motinova::DecodeOptions& protocol) {
  std::vector<std::string> levels;
  for (std::uint8_t value = 0; value <= 4; ++value) {
    for (const auto& a : protocol.assist_names) {
      if (a.value == value) {
        levels.push_back(a.name);
        break;
      }
    }
  }
  return levels;
}

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

}  // namespace

std::vector<std::string> zone_bundle_topics(const config::Config& config) {
  const auto& g = config.geofence;
  std::vector<std::string> topics{g.bundle_topic.empty() ? config.mqtt.topic_prefix + "/zones"
                                                         : g.bundle_topic};
  if (g.vehicle_bundles) {
    topics.push_back(config.mqtt.topic_prefix + "/" + config.vehicle.id + "/zones");
  }
  return topics;
}

void Pipeline::record_zone_event(const geofence::ZoneEvent& e) {
  // The speed authority names the slow zone behind a limit in an operator's result.
  commands_->speed_authority().on_zone_event(e, common::untrusted_excerpt(e.zone_name, 64));
  // Campaigns triggered by a zone (issue 29) follow the same confirmed state.
  if (campaigns_ && (e.transition == geofence::Transition::kEnter ||
                     e.transition == geofence::Transition::kExit)) {
    campaigns_->on_zone(e.zone_id, e.zone_name, e.transition == geofence::Transition::kEnter);
  }
  // The name comes from a signed bundle but is still received text: one escaped log line.
  spdlog::info("geofence: {} {} zone '{}' ('{}') at {}, bundle version {}",
               geofence::transition_name(e.transition), geofence::zone_kind_name(e.kind), e.zone_id,
               common::untrusted_excerpt(e.zone_name, 128),
               e.position ? fmt::format("{:.6f},{:.6f}", e.position->lat_deg, e.position->lon_deg)
                          : std::string("an unknown position"),
               e.bundle_version);
  const std::string payload = geofence::zone_event_payload(e);
  recorder_->record_zone_event(zone_record(e), storage::Bytes(payload.begin(), payload.end()));
}

void Pipeline::update_area_alarm(Micros wall, const std::optional<gnss::Fix>& position) {
  const bool outside = zones_->demands(wall).outside_operating_area;
  if (outside == outside_operating_area_) return;
  outside_operating_area_ = outside;
  storage::AlarmRow rec;
  rec.kind = "outside_operating_area";
  rec.transition = outside ? storage::AlarmTransition::kRaised : storage::AlarmTransition::kCleared;
  rec.ts_us = wall.count();
  if (outside) area_alarm_since_ = wall;
  rec.first_evidence_us = area_alarm_since_.count();
  rec.detail = fmt::format(
      "{} at {}", outside ? "outside every operating area" : "inside an operating area again",
      position ? fmt::format("{:.6f},{:.6f}", position->lat_deg, position->lon_deg)
               : std::string("an unknown position"));
  spdlog::warn("geofence: alarm outside_operating_area {}: {}", outside ? "raised" : "cleared",
               rec.detail);
  state_throttle_.touch();  // listed in the retained state's active_alarms while raised
  auto payload = domain::alarm_payload(rec, {});
  recorder_->record_alarm(std::move(rec), std::move(payload));
  request_settle();
}

void Pipeline::start_zones(const config::Config& config) {
  if (!config.geofence.enabled) return;
  const auto& g = config.geofence;
  geofence::ZoneControllerConfig zc;
  zc.engine.margin_m = g.margin_m;
  zc.engine.min_dwell = std::chrono::milliseconds(g.min_dwell_ms);
  zc.engine.speed_ramp = std::chrono::milliseconds(g.speed_ramp_ms);
  zc.engine.assist_fade = std::chrono::milliseconds(g.assist_fade_ms);
  zc.engine.restore_ramp = std::chrono::milliseconds(g.restore_ramp_ms);
  zc.engine.unrestricted_kmh = g.own_limit_kmh;
  zc.engine.refuse_ride_ending_locks = g.refuse_ride_ending_locks;
  zc.engine.vehicle_type_id = config.vehicle.type_id;  // GBFS rules for this bike's type (issue 27)
  zc.enforcer.own_limit_kmh = g.own_limit_kmh;
  // One authority for the speed limit (issue 24): the zones' demand and the operator's cap
  // (from speed-limit commands) meet in the command service's, which outlives zones_.
  auto& speed = commands_->speed_authority();
  speed.set_own_limit(g.own_limit_kmh);
  zc.enforcer.speed = &speed;
  zc.enforcer.assist_levels = enforcer_assist_levels(config.protocol);
  zc.trusted_keys = config.command.trusted_keys;
  // Issue 28: a bundle signed under a root's delegation with the action "zones".
  if (!config.command.root_keys.empty()) {
    zc.delegated_check = commands_->delegated_document_check("zones");
  }
  zc.vehicle_id = config.vehicle.id;  // a bundle signed for another vehicle is refused
  zc.bundle_file = g.bundle_file;
  zone_bundle_file_ = g.bundle_file;
  // The stored file is held to the same limit as the topic: what was accepted is restored.
  zc.limits.max_payload_bytes = static_cast<std::size_t>(g.max_bundle_bytes);
  zones_ = std::make_unique<geofence::ZoneController>(std::move(zc));
  // No-parking zones judge lock commands at the fix current NOW (a stale or unknown position
  // never refuses a lock: a rider must always be able to end a ride).
  commands_->set_lock_guard([this](bool ride_ending, Micros) -> std::optional<std::string> {
    std::optional<gnss::Fix> fix;
    if (gnss_) fix = gnss_->state().current(gnss_->wall_now());
    const auto verdict = zones_->parking(fix ? &*fix : nullptr, ride_ending, env_.wall_now());
    if (verdict.event) record_zone_event(*verdict.event);
    if (!verdict.refuse) return std::nullopt;
    return fmt::format("will not end the ride inside the no-parking zone '{}'",
                       verdict.event ? verdict.event->zone_id : std::string("?"));
  });
  // No-start zones (issue 27) judge unlock commands the same way: a ride is not started
  // clearly inside one; an unknown position never refuses.
  commands_->set_unlock_guard([this](bool ride_starting, Micros) -> std::optional<std::string> {
    std::optional<gnss::Fix> fix;
    if (gnss_) fix = gnss_->state().current(gnss_->wall_now());
    const auto verdict = zones_->starting(fix ? &*fix : nullptr, ride_starting, env_.wall_now());
    if (verdict.event) record_zone_event(*verdict.event);
    if (!verdict.refuse) return std::nullopt;
    return fmt::format("will not start a ride inside the no-start zone '{}'",
                       verdict.event ? verdict.event->zone_id : std::string("?"));
  });
  // A lock made on the bike is only noted here (the recorder is mid-message); settle() judges.
  recorder_->trackers().set_lock_observer([this](const storage::LockEventRow& ev, int new_raw) {
    if (!bike_locks_.on_lock_event(ev.kind, new_raw, ev.cause)) return;
    BikeLock lock{.wall = env_.wall_now(), .fix = std::nullopt};
    if (gnss_) lock.fix = gnss_->state().current(gnss_->wall_now());
    pending_bike_locks_.push_back(std::move(lock));
    request_settle();
  });
  std::string error;
  std::vector<geofence::ZoneEvent> events;
  const auto verdict = zones_->restore(env_.wall_now(), error, events);
  for (const auto& e : events) record_zone_event(e);
  if (!error.empty()) {
    spdlog::warn("geofence: {}: no zones until a bundle arrives", error);
  } else if (!verdict) {
    spdlog::info("geofence: no stored bundle at {}: no zones until one arrives", g.bundle_file);
  } else if (verdict->accepted()) {
    spdlog::info("geofence: {} (stored in {})", verdict->detail, g.bundle_file);
  } else {
    spdlog::warn("geofence: stored bundle {} refused ({}): {}", g.bundle_file,
                 geofence::bundle_refusal_name(verdict->reason), verdict->detail);
  }
}

void Pipeline::apply_zones(Micros wall, const std::optional<gnss::Fix>& position) {
  std::vector<geofence::ZoneEvent> events;
  zones_->on_position(wall, position ? &*position : nullptr, events);
  for (const auto& e : events) record_zone_event(e);
  if (!events.empty()) request_settle();
  update_area_alarm(wall, position);
}

void Pipeline::on_zone_bundle(const uplink::ZoneBundleMessage& m) {
  const Micros wall = env_.wall_now();
  std::optional<gnss::Fix> fix;
  if (gnss_) fix = gnss_->state().current(gnss_->wall_now());
  std::vector<geofence::ZoneEvent> events;
  std::string persist_error;
  // Located at once with the current fix: a replaced bundle does not wait for the next one.
  const auto verdict = m.oversized_bytes > 0
                           ? zones_->on_oversized(m.oversized_bytes, max_bundle_bytes_, wall)
                           : zones_->on_bundle(bytes_of(m.payload), wall, events, persist_error,
                                               fix ? &*fix : nullptr,
                                               zone_topics_.size() > 1 && m.topic == zone_topics_[1]
                                                   ? geofence::BundleTopic::kVehicle
                                                   : geofence::BundleTopic::kFleet);
  for (const auto& e : events) record_zone_event(e);
  if (verdict.accepted()) {
    bundle_refusal_logged_.clear();
    spdlog::info("geofence: bundle on {} accepted: {}", m.topic, verdict.detail);
    if (!persist_error.empty()) {
      spdlog::error("geofence: bundle version {} enforced but not stored: {}", verdict.version,
                    persist_error);
    }
  } else if (verdict.outcome == geofence::BundleOutcome::kRefused) {
    bundle_refusal_topic_ = m.topic;
    // A retained bundle comes again on every reconnect: its refusal is news only once.
    std::string what = fmt::format("{} refused ({}): {}", m.topic,
                                   geofence::bundle_refusal_name(verdict.reason), verdict.detail);
    if (what != bundle_refusal_logged_) {
      spdlog::warn("geofence: bundle on {}; {}", what,
                   verdict.in_force > 0 ? fmt::format("version {} stays in force", verdict.in_force)
                                        : std::string("no zones in force"));
      bundle_refusal_logged_ = std::move(what);
    }
  } else {
    spdlog::debug("geofence: bundle on {}: {}", m.topic, verdict.detail);
  }
  update_area_alarm(wall, fix);
  state_throttle_.touch();
  request_settle();
}

void Pipeline::judge_bike_locks() {
  for (const auto& lock : std::exchange(pending_bike_locks_, {})) {
    // Report only (ride_ending false): the lock has happened, there is nothing to refuse.
    const auto verdict = zones_->parking(lock.fix ? &*lock.fix : nullptr, false, lock.wall);
    if (verdict.event) record_zone_event(*verdict.event);
  }
}

std::optional<GeofenceStatus> Pipeline::geofence_status() const {
  if (!zones_) return std::nullopt;
  GeofenceStatus g;
  if (const auto& f = zones_->authority().in_force()) {
    g.version = f->zones->version;
    g.zones = f->zones->zones.size();
    g.vertices = f->zones->vertices;
    g.key_id = f->key_id;
    g.issued_at_us = f->zones->issued_at.count();
  }
  g.bundle_file = zone_bundle_file_;
  g.topics = zone_topics_;
  g.counters = zones_->counters();
  if (uplink_) g.dropped = uplink_->stats().zone_bundles_dropped;
  g.last_refusal_topic = bundle_refusal_topic_;
  g.outside_operating_area = outside_operating_area_;
  return g;
}

void Pipeline::tick_zones() {
  const Micros wall = env_.wall_now();
  geofence::McView mc;
  mc.assist_level = core_.live().assist;
  // The limit in force as the MC last reported it: the enforcer writes the authority's limit
  // only when it differs.
  if (const auto limit = core_.live().speed_limit_kmh)
    mc.speed_limit_kmh = static_cast<int>(std::lround(*limit));
  mc.busy = zone_write_running_ || commands_->busy();
  // A zone's time window opening or closing around the bike is an event (issue 27).
  std::vector<geofence::ZoneEvent> events;
  const auto write = zones_->tick(wall, mc, events);
  for (const auto& e : events) record_zone_event(e);
  if (!events.empty()) {
    std::optional<gnss::Fix> fix;
    if (gnss_) fix = gnss_->state().current(gnss_->wall_now());
    update_area_alarm(wall, fix);
  }
  if (!write) return;
  command::McRequest request;
  std::string what;
  if (write->kind == geofence::McWrite::Kind::kSpeedLimit) {
    request.kind = command::McActionKind::kSpeedLimit;
    request.speed_limit_kmh = static_cast<std::uint32_t>(write->speed_limit_kmh);
    what = fmt::format("speed limit {} km/h", write->speed_limit_kmh);
  } else {
    request.kind = command::McActionKind::kAssistLevel;
    request.assist_level = write->assist_level;
    what = "assist level " + write->assist_level;
  }
  // The write acts on the bus as it is now, not as of the last batch.
  if (bus_.sim) bus_.sim->flush();
  auto done = [this, what, token = std::weak_ptr<int>(alive_)](bool ok, std::string reason,
                                                               Micros) {
    if (token.expired()) return;
    zone_write_running_ = false;
    if (ok) {
      spdlog::info("geofence: MC {} confirmed", what);
    } else {
      spdlog::warn("geofence: MC {} not confirmed: {}", what, reason);
    }
    zones_->on_write_result(ok, env_.wall_now());
    request_settle();
  };
  spdlog::debug("geofence: MC {} (zone demand)", what);
  // Set before the start: a runner that refuses on its re-check completes at once, inside it.
  zone_write_running_ = true;
  if (auto refused = commands_->start_own_mc_action(request, bus_now(), std::move(done))) {
    zone_write_running_ = false;
    // Retried every few seconds (a parked bike's MC may sleep for hours): logged once a reason.
    std::string why =
        fmt::format("{}: {}", command::reject_reason_name(refused->reason), refused->detail);
    if (why != zone_refusal_) {
      spdlog::info("geofence: MC {} not started now ({}); retried", what, why);
      zone_refusal_ = std::move(why);
    }
    zones_->on_write_result(false, wall);
    return;
  }
  zone_refusal_.clear();
}

StageRun Pipeline::ZonesStage::run(EngineTime) {
  if (!p_.pending_bike_locks_.empty()) p_.judge_bike_locks();
  p_.tick_zones();
  return {};
}

std::optional<std::chrono::steady_clock::time_point> Pipeline::zones_deadline() const {
  // The zones' deadlines are wall time (positions are judged by when they were received).
  const Micros now = env_.wall_now();
  const auto next = zones_->next_deadline(now);
  if (!next) return std::nullopt;
  return env_.steady_now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::max(*next - now, Micros(0)));
}

}  // namespace fleetgw::runtime
