// ZonesStage (zones_stage.h): the geofence's policy, moved out of the Pipeline (issue 26).
#include "gateway/runtime/zones_stage.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>

#include "gateway/common/untrusted_text.h"
#include "gateway/domain/alarm_payload.h"
#include "gateway/geofence/zone_payload.h"

namespace fleetgw::runtime {

namespace {

storage::ZoneEventRow zone_row(const geofence::ZoneEvent& e) {
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

std::string position_text(const std::optional<gnss::Fix>& p) {
  return p ? fmt::format("{:.6f},{:.6f}", p->lat_deg, p->lon_deg)
           : std::string("an unknown position");
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

ZonesStageConfig make_zones_stage_config(const config::Config& config) {
  const auto& g = config.geofence;
  ZonesStageConfig c;
  auto& zc = c.controller;
  zc.engine.margin_m = g.margin_m;
  zc.engine.min_dwell = std::chrono::milliseconds(g.min_dwell_ms);
  zc.engine.speed_ramp = std::chrono::milliseconds(g.speed_ramp_ms);
  zc.engine.assist_fade = std::chrono::milliseconds(g.assist_fade_ms);
  zc.engine.restore_ramp = std::chrono::milliseconds(g.restore_ramp_ms);
  zc.engine.unrestricted_kmh = g.own_limit_kmh;
  zc.engine.refuse_ride_ending_locks = g.refuse_ride_ending_locks;
  zc.engine.vehicle_type_id = config.vehicle.type_id;  // GBFS rules for this bike's type (issue 27)
  zc.enforcer.own_limit_kmh = g.own_limit_kmh;
  zc.enforcer.assist_levels = enforcer_assist_levels(config.protocol);
  zc.trusted_keys = config.command.trusted_keys;
  zc.vehicle_id = config.vehicle.id;  // a bundle signed for another vehicle is refused
  zc.bundle_file = g.bundle_file;
  // The stored file is held to the same limit as the topic: what was accepted is restored.
  zc.limits.max_payload_bytes = static_cast<std::size_t>(g.max_bundle_bytes);
  if (config.mqtt.enabled) c.topics = zone_bundle_topics(config);
  c.max_bundle_bytes = static_cast<std::size_t>(g.max_bundle_bytes);
  return c;
}

ZonesStage::ZonesStage(ZonesStageConfig config, Env& env)
    : env_(env),
      controller_(config.controller),
      topics_(std::move(config.topics)),
      bundle_file_(config.controller.bundle_file.string()),
      max_bundle_bytes_(config.max_bundle_bytes) {}

void ZonesStage::restore() {
  std::string error;
  std::vector<geofence::ZoneEvent> events;
  const auto verdict = controller_.restore(env_.wall_now(), error, events);
  for (const auto& e : events) emit(e);
  if (!error.empty()) {
    spdlog::warn("geofence: {}: no zones until a bundle arrives", error);
  } else if (!verdict) {
    spdlog::info("geofence: no stored bundle at {}: no zones until one arrives", bundle_file_);
  } else if (verdict->accepted()) {
    spdlog::info("geofence: {} (stored in {})", verdict->detail, bundle_file_);
  } else {
    spdlog::warn("geofence: stored bundle {} refused ({}): {}", bundle_file_,
                 geofence::bundle_refusal_name(verdict->reason), verdict->detail);
  }
}

std::optional<EngineTime> ZonesStage::next_deadline() const {
  if (inputs_waiting()) return env_.steady_now();
  // The zones' deadlines are wall time (positions are judged by when they were received).
  const Micros now = env_.wall_now();
  const auto next = controller_.next_deadline(now);
  if (!next) return std::nullopt;
  return env_.steady_now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::max(*next - now, Micros(0)));
}

void ZonesStage::on_position(Micros wall, std::optional<gnss::Fix> position) {
  fix_ = position;
  positions_.push_back({wall, std::move(position)});
}

void ZonesStage::on_bundle(uplink::ZoneBundleMessage message) {
  bundles_.push_back(std::move(message));
}

void ZonesStage::on_lock_event(std::string_view kind, int new_raw, std::string_view cause) {
  if (!bike_locks_.on_lock_event(kind, new_raw, cause)) return;
  bike_locks_pending_.push_back({env_.wall_now(), fix_});
}

StageRun ZonesStage::run(EngineTime) {
  const Micros wall = env_.wall_now();
  for (const auto& m : std::exchange(bundles_, {})) handle_bundle(m, wall);
  for (const auto& p : std::exchange(positions_, {})) {
    std::vector<geofence::ZoneEvent> events;
    controller_.on_position(p.wall, p.fix ? &*p.fix : nullptr, events);
    for (const auto& e : events) emit(e);
    update_area_alarm(p.wall, p.fix);
  }
  for (const auto& lock : std::exchange(bike_locks_pending_, {})) {
    // Report only (ride_ending false): the lock has happened, there is nothing to refuse.
    const auto verdict = controller_.parking(lock.fix ? &*lock.fix : nullptr, false, lock.wall);
    if (verdict.event) emit(*verdict.event);
  }
  tick(wall);
  return {.produced = records.size() + alarms.size() + (mc_write ? 1u : 0u), .status = {}};
}

void ZonesStage::emit(const geofence::ZoneEvent& e) {
  // The name comes from a signed bundle but is still received text: one escaped log line.
  spdlog::info("geofence: {} {} zone '{}' ('{}') at {}, bundle version {}",
               geofence::transition_name(e.transition), geofence::zone_kind_name(e.kind), e.zone_id,
               common::untrusted_excerpt(e.zone_name, 128), position_text(e.position),
               e.bundle_version);
  const std::string payload = geofence::zone_event_payload(e);
  records.push_back({e, zone_row(e), storage::Bytes(payload.begin(), payload.end())});
}

void ZonesStage::update_area_alarm(Micros wall, const std::optional<gnss::Fix>& position) {
  const bool outside = controller_.demands(wall).outside_operating_area;
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
      position_text(position));
  spdlog::warn("geofence: alarm outside_operating_area {}: {}", outside ? "raised" : "cleared",
               rec.detail);
  state_touched_ = true;  // listed in the retained state's active_alarms while raised
  auto payload = domain::alarm_payload(rec, {});
  alarms.push_back({std::move(rec), std::move(payload)});
}

void ZonesStage::handle_bundle(const uplink::ZoneBundleMessage& m, Micros wall) {
  std::vector<geofence::ZoneEvent> events;
  std::string persist_error;
  const auto topic = topics_.size() > 1 && m.topic == topics_[1] ? geofence::BundleTopic::kVehicle
                                                                 : geofence::BundleTopic::kFleet;
  // Located at once with the current fix: a replaced bundle does not wait for the next one.
  const auto verdict =
      m.oversized_bytes > 0
          ? controller_.on_oversized(m.oversized_bytes, max_bundle_bytes_, wall)
          : controller_.on_bundle(bytes_of(m.payload), wall, events, persist_error, fix(), topic);
  for (const auto& e : events) emit(e);
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
  update_area_alarm(wall, fix_);
  state_touched_ = true;
}

void ZonesStage::tick(Micros wall) {
  geofence::McView mc = mc_;
  mc.busy = write_running_ || mc_.busy;
  // A zone's time window opening or closing around the bike is an event (issue 27).
  std::vector<geofence::ZoneEvent> events;
  const auto write = controller_.tick(wall, mc, events);
  for (const auto& e : events) emit(e);
  if (!events.empty()) update_area_alarm(wall, fix_);
  if (!write) return;
  McWriteRequest out;
  if (write->kind == geofence::McWrite::Kind::kSpeedLimit) {
    out.request.kind = command::McActionKind::kSpeedLimit;
    out.request.speed_limit_kmh = static_cast<std::uint32_t>(write->speed_limit_kmh);
    out.what = fmt::format("speed limit {} km/h", write->speed_limit_kmh);
  } else {
    out.request.kind = command::McActionKind::kAssistLevel;
    out.request.assist_level = write->assist_level;
    out.what = "assist level " + write->assist_level;
  }
  spdlog::debug("geofence: MC {} (zone demand)", out.what);
  // Running from now: a runner that refuses on its re-check completes at once, inside the
  // start, and that completion must find the write running.
  write_running_ = true;
  write_at_ = wall;
  write_what_ = out.what;
  mc_write = std::move(out);
}

void ZonesStage::on_write_started() {
  write_refusal_.clear();
}

void ZonesStage::on_write_refused(std::string why) {
  write_running_ = false;
  // Retried every few seconds (a parked bike's MC may sleep for hours): logged once a reason.
  if (why != write_refusal_) {
    spdlog::info("geofence: MC {} not started now ({}); retried", write_what_, why);
    write_refusal_ = std::move(why);
  }
  controller_.on_write_result(false, write_at_);
}

void ZonesStage::on_write_done(bool ok, std::string_view reason) {
  write_running_ = false;
  if (ok) {
    spdlog::info("geofence: MC {} confirmed", write_what_);
  } else {
    spdlog::warn("geofence: MC {} not confirmed: {}", write_what_, reason);
  }
  controller_.on_write_result(ok, env_.wall_now());
}

std::optional<std::string> ZonesStage::judge_lock(bool ride_ending) {
  const auto verdict = controller_.parking(fix(), ride_ending, env_.wall_now());
  if (verdict.event) emit(*verdict.event);
  if (!verdict.refuse) return std::nullopt;
  return fmt::format("will not end the ride inside the no-parking zone '{}'",
                     verdict.event ? verdict.event->zone_id : std::string("?"));
}

std::optional<std::string> ZonesStage::judge_unlock(bool ride_starting) {
  const auto verdict = controller_.starting(fix(), ride_starting, env_.wall_now());
  if (verdict.event) emit(*verdict.event);
  if (!verdict.refuse) return std::nullopt;
  return fmt::format("will not start a ride inside the no-start zone '{}'",
                     verdict.event ? verdict.event->zone_id : std::string("?"));
}

}  // namespace fleetgw::runtime
