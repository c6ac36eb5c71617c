#include "gateway/geofence/zone_engine.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace fleetgw::geofence {

std::string_view zone_kind_name(ZoneKind kind) {
  switch (kind) {
    case ZoneKind::kOperatingArea:
      return "operating_area";
    case ZoneKind::kSlow:
      return "slow";
    case ZoneKind::kNoRide:
      return "no_ride";
    case ZoneKind::kNoParking:
      return "no_parking";
    case ZoneKind::kNoStart:
      return "no_start";
    case ZoneKind::kRules:
      return "rules";
  }
  return "unknown";
}

std::string_view transition_name(Transition t) {
  switch (t) {
    case Transition::kEnter:
      return "enter";
    case Transition::kExit:
      return "exit";
    case Transition::kLockedInNoParking:
      return "locked_in_no_parking";
    case Transition::kLockRefused:
      return "lock_refused";
    case Transition::kUnlockRefused:
      return "unlock_refused";
  }
  return "unknown";
}

bool ZoneRuleSpec::applies_to(std::string_view vehicle_type_id) const {
  return vehicle_type_ids.empty() || std::find(vehicle_type_ids.begin(), vehicle_type_ids.end(),
                                               vehicle_type_id) != vehicle_type_ids.end();
}

std::optional<Effects> EnforcedZone::effects_for(std::string_view vehicle_type_id) const {
  Effects e;
  switch (kind) {
    case ZoneKind::kOperatingArea:
      return e;
    case ZoneKind::kSlow:
      e.speed_limit_kmh = speed_limit_kmh;
      return e;
    case ZoneKind::kNoRide:
      e.no_ride = true;
      return e;
    case ZoneKind::kNoParking:
      e.no_parking = true;
      return e;
    case ZoneKind::kNoStart:
      e.no_start = true;
      return e;
    case ZoneKind::kRules:
      break;
  }
  // GBFS: the first rule for the vehicle's type; none, and the zone is not there for it.
  for (const auto& r : rules) {
    if (r.applies_to(vehicle_type_id)) return r.effects;
  }
  return std::nullopt;
}

void Ramp::retarget(double to, Micros now, Micros duration) {
  if (to == to_) return;
  from_ = value(now);
  to_ = to;
  start_ = now;
  duration_ = std::max(duration, Micros(0));
}

double Ramp::value(Micros now) const {
  if (settled(now)) return to_;
  if (now <= start_) return from_;
  const double f =
      static_cast<double>((now - start_).count()) / static_cast<double>(duration_.count());
  return from_ + (to_ - from_) * f;
}

int Ramp::whole(Micros now) const {
  const double v = value(now);
  // Falling: never below the ramp (the rider is slowed no faster than configured); rising:
  // never above it. The end points are whole numbers, so both reach them exactly.
  return static_cast<int>(to_ < from_ ? std::ceil(v) : std::floor(v));
}

std::optional<Micros> Ramp::next_step(Micros now) const {
  if (settled(now)) return std::nullopt;
  const int w = whole(now);
  // The level at which whole() changes, and the time the ramp reaches it.
  const double level = to_ < from_ ? w - 1.0 : w + 1.0;
  const double f = (level - from_) / (to_ - from_);
  if (!(f > 0) || f >= 1) return start_ + duration_;
  const auto at =
      start_ +
      Micros(static_cast<std::int64_t>(std::ceil(f * static_cast<double>(duration_.count())))) +
      Micros(1);  // past the rounding of value() at exactly that instant
  return std::max(at, now + Micros(1));
}

ZoneEngine::ZoneEngine(EngineConfig config)
    : config_(config), speed_(config.unrestricted_kmh), assist_(100.0) {}

std::optional<bool> ZoneEngine::inside(std::size_t index) const {
  if (index >= states_.size() || states_[index].confirmed == Side::kUnknown) return std::nullopt;
  return states_[index].confirmed == Side::kInside;
}

ZoneEvent ZoneEngine::event_for(const EnforcedZone& zone, Transition t, Micros now,
                                const std::optional<gnss::Fix>& where) const {
  ZoneEvent e;
  e.zone_id = zone.id;
  e.zone_name = zone.name;
  e.kind = zone.kind;
  e.transition = t;
  e.at = now;
  e.position = where;
  e.bundle_version = zones_ ? zones_->version : 0;
  e.speed_limit_kmh = zone.kind == ZoneKind::kSlow ? zone.speed_limit_kmh : 0;
  if (zone.kind == ZoneKind::kRules) {
    if (const auto fx = zone.effects_for(config_.vehicle_type_id); fx && fx->speed_limit_kmh) {
      e.speed_limit_kmh = *fx->speed_limit_kmh;
    }
  }
  return e;
}

bool ZoneEngine::live(std::size_t i, Micros now) const {
  return effects_[i].has_value() && zones_->zones[i].exists_at(now);
}

void ZoneEngine::set_zones(std::shared_ptr<const ZoneSet> zones, Micros now,
                           std::vector<ZoneEvent>& events) {
  std::map<std::string_view, std::size_t> kept;
  if (zones) {
    for (std::size_t i = 0; i < zones->zones.size(); ++i) kept.emplace(zones->zones[i].id, i);
  }
  std::vector<State> next(zones ? zones->zones.size() : 0);
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      const auto& old = zones_->zones[i];
      const auto it = kept.find(old.id);
      if (it != kept.end()) {
        next[it->second] = states_[i];
      } else if (states_[i].confirmed == Side::kInside && (i >= existed_.size() || existed_[i])) {
        // Its effects end with it: say so, as if the bike had left it.
        events.push_back(event_for(old, Transition::kExit, now, last_fix_));
      }
    }
  }
  zones_ = std::move(zones);
  states_ = std::move(next);
  effects_.assign(states_.size(), std::nullopt);
  existed_.assign(states_.size(), false);
  default_effects_.reset();
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      effects_[i] = zones_->zones[i].effects_for(config_.vehicle_type_id);
      existed_[i] = zones_->zones[i].exists_at(now);
      // A zone not for this bike (another vehicle type) is never located: no state to keep.
      if (!effects_[i]) states_[i] = State{};
    }
    for (const auto& r : zones_->default_rules) {
      if (r.applies_to(config_.vehicle_type_id)) {
        default_effects_ = r.effects;
        break;
      }
    }
  }
  update_targets(now);
}

void ZoneEngine::advance(Micros now, std::vector<ZoneEvent>& events) {
  if (!zones_) return;
  bool changed = false;
  for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
    const bool exists = zones_->zones[i].exists_at(now);
    if (exists == existed_[i]) continue;
    existed_[i] = exists;
    changed = true;
    // The window opened or closed around a bike that stayed inside: the zone came or went.
    if (effects_[i] && states_[i].confirmed == Side::kInside) {
      events.push_back(event_for(zones_->zones[i], exists ? Transition::kEnter : Transition::kExit,
                                 now, last_fix_));
    }
  }
  if (changed) update_targets(now);
}

Demands ZoneEngine::step(Micros now, const gnss::Fix* fix, std::vector<ZoneEvent>& events) {
  if (fix == nullptr) {
    for (auto& s : states_) s.pending = Side::kUnknown;
    advance(now, events);
    return demands(now);
  }
  last_fix_ = *fix;
  advance(now, events);
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      if (!effects_[i]) continue;  // not for this bike's type
      const EnforcedZone& zone = zones_->zones[i];
      const bool exists = existed_[i];
      State& s = states_[i];
      const Where w = zone.shape.locate(fix->lat_deg, fix->lon_deg, config_.margin_m);
      const Side side = w == Where::kInside    ? Side::kInside
                        : w == Where::kOutside ? Side::kOutside
                                               : Side::kUnknown;
      if (side == Side::kUnknown || side == s.confirmed) {
        s.pending = Side::kUnknown;  // within the margin, or back: the dwell starts over
        continue;
      }
      if (s.pending != side) {
        s.pending = side;
        s.pending_since = now;
      }
      if (now - s.pending_since < config_.min_dwell) continue;
      const Side before = s.confirmed;
      s.confirmed = side;
      s.pending = Side::kUnknown;
      if (!exists) continue;  // outside its window: tracked, but silent
      if (side == Side::kInside) {
        events.push_back(event_for(zone, Transition::kEnter, now, *fix));
      } else if (before == Side::kInside) {
        events.push_back(event_for(zone, Transition::kExit, now, *fix));
      }
    }
  }
  update_targets(now);
  return demands(now);
}

void ZoneEngine::relocate(Micros now, const gnss::Fix& fix, std::vector<ZoneEvent>& events) {
  if (!zones_) return;
  last_fix_ = fix;
  advance(now, events);
  for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
    if (!effects_[i]) continue;  // not for this bike's type
    const EnforcedZone& zone = zones_->zones[i];
    State& s = states_[i];
    const Where w = zone.shape.locate(fix.lat_deg, fix.lon_deg, config_.margin_m);
    if (w == Where::kNearBoundary) continue;
    const Side side = w == Where::kInside ? Side::kInside : Side::kOutside;
    s.pending = Side::kUnknown;
    if (side == s.confirmed) continue;
    const Side before = std::exchange(s.confirmed, side);
    if (!existed_[i]) continue;  // outside its window: tracked, but silent
    if (side == Side::kInside) {
      events.push_back(event_for(zone, Transition::kEnter, now, fix));
    } else if (before == Side::kInside) {
      events.push_back(event_for(zone, Transition::kExit, now, fix));
    }
  }
  update_targets(now);
}

void ZoneEngine::update_targets(Micros now) {
  const Effects fx = effective(now);
  double speed = config_.unrestricted_kmh;
  // 0 km/h is GBFS's "stop": the assistance fades to off; the MC is never given 0.
  if (fx.speed_limit_kmh && *fx.speed_limit_kmh > 0) {
    speed = std::min<double>(speed, *fx.speed_limit_kmh);
  }
  const bool no_ride = fx.no_ride || (fx.speed_limit_kmh && *fx.speed_limit_kmh == 0);
  speed_.retarget(speed, now,
                  speed < speed_.value(now) ? config_.speed_ramp : config_.restore_ramp);
  assist_.retarget(no_ride ? 0.0 : 100.0, now,
                   no_ride ? config_.assist_fade : config_.restore_ramp);
}

Effects ZoneEngine::effective(Micros now) const {
  Effects fx;
  if (!zones_) return fx;
  const bool first_match = zones_->precedence == Precedence::kFirstMatch;
  bool all_outside = true;
  for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
    const EnforcedZone& zone = zones_->zones[i];
    if (zone.kind == ZoneKind::kOperatingArea || !live(i, now)) continue;
    const Side side = states_[i].confirmed;
    if (side != Side::kInside) {
      all_outside = all_outside && side == Side::kOutside;
      continue;
    }
    const Effects& z = *effects_[i];
    if (first_match) return z;  // GBFS: the first zone listed wins
    if (z.speed_limit_kmh) {
      fx.speed_limit_kmh = std::min(fx.speed_limit_kmh.value_or(z.speed_limit_kmh.value()),
                                    z.speed_limit_kmh.value());
    }
    fx.no_ride = fx.no_ride || z.no_ride;
    fx.no_parking = fx.no_parking || z.no_parking;
    fx.no_start = fx.no_start || z.no_start;
  }
  // Outside every zone (each one known to be outside): the default rules.
  if (first_match && all_outside && default_effects_) return *default_effects_;
  return fx;
}

Demands ZoneEngine::demands(Micros now) const {
  Demands d;
  // Once back at the bike's own limit there is nothing to enforce: no zone limit at all.
  if (!speed_.settled(now) || speed_.target() < config_.unrestricted_kmh) {
    d.speed_limit_kmh = std::min(speed_.whole(now), config_.unrestricted_kmh);
  }
  d.assist_cap_percent = std::clamp(assist_.whole(now), 0, 100);
  if (zones_) {
    bool any_area = false, inside_area = false, every_area_known = true;
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      const EnforcedZone& zone = zones_->zones[i];
      const Side side = states_[i].confirmed;
      if (zone.kind == ZoneKind::kOperatingArea && live(i, now)) {
        any_area = true;
        inside_area = inside_area || side == Side::kInside;
        every_area_known = every_area_known && side != Side::kUnknown;
      }
    }
    d.outside_operating_area = any_area && !inside_area && every_area_known;
    const Effects fx = effective(now);
    d.in_no_parking_zone = fx.no_parking;
    d.in_no_start_zone = fx.no_start;
  }
  return d;
}

std::optional<Micros> ZoneEngine::next_change(Micros now) const {
  auto a = speed_.next_step(now);
  const auto b = assist_.next_step(now);
  if (b && (!a || *b < *a)) a = b;
  // The next window edge of a zone for this bike: advance() must run then.
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      if (!effects_[i]) continue;
      for (const Micros edge : {zones_->zones[i].start, zones_->zones[i].end}) {
        if (edge.count() != 0 && edge > now && (!a || edge < *a)) a = edge;
      }
    }
  }
  return a;
}

ZoneEngine::Judged ZoneEngine::judge(const gnss::Fix& fix, Micros now,
                                     bool Effects::*effect) const {
  Judged j;
  const bool first_match = zones_->precedence == Precedence::kFirstMatch;
  bool all_outside = true;
  for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
    const EnforcedZone& zone = zones_->zones[i];
    if (zone.kind == ZoneKind::kOperatingArea || !live(i, now)) continue;
    const Where w = zone.shape.locate(fix.lat_deg, fix.lon_deg, config_.margin_m);
    if (w == Where::kOutside) continue;
    all_outside = false;
    if ((*effects_[i]).*effect) {
      j.near = true;
      if (j.zone == nullptr) j.zone = &zone;
      if (w == Where::kInside) {
        j.inside = true;
        j.zone = &zone;
        return j;
      }
    }
    // GBFS: a zone the fix is clearly inside decides, whatever comes after it.
    if (first_match && w == Where::kInside) return j;
  }
  if (first_match && all_outside && default_effects_ && (*default_effects_).*effect) {
    j.near = j.inside = j.by_default = true;
  }
  return j;
}

ParkingVerdict ZoneEngine::verdict_of(const Judged& j, const gnss::Fix& fix, Micros now,
                                      Transition reported, Transition refused, bool refuse) const {
  ParkingVerdict v;
  if (!j.near) return v;
  v.in_no_parking_zone = true;
  v.refuse = refuse && j.inside;
  const Transition t = v.refuse ? refused : reported;
  if (j.by_default) {
    // The default rules outside every zone have no zone of their own: named as GBFS names them.
    ZoneEvent e;
    e.zone_id = "global_rules";
    e.zone_name = "outside every zone";
    e.kind = ZoneKind::kRules;
    e.transition = t;
    e.at = now;
    e.position = fix;
    e.bundle_version = zones_->version;
    v.event = std::move(e);
  } else {
    v.event = event_for(*j.zone, t, now, fix);
  }
  return v;
}

ParkingVerdict ZoneEngine::parking(const gnss::Fix* fix, bool ride_ending, Micros now) const {
  if (fix == nullptr || !zones_) return {};
  return verdict_of(judge(*fix, now, &Effects::no_parking), *fix, now,
                    Transition::kLockedInNoParking, Transition::kLockRefused,
                    ride_ending && config_.refuse_ride_ending_locks);
}

ParkingVerdict ZoneEngine::starting(const gnss::Fix* fix, bool ride_starting,
                                    Micros now) const {
  if (fix == nullptr || !zones_ || !ride_starting) return {};
  auto v = verdict_of(judge(*fix, now, &Effects::no_start), *fix, now, Transition::kUnlockRefused,
                      Transition::kUnlockRefused, true);
  // Only a refusal is news: an unlock within the margin of a no-start zone runs unreported.
  if (!v.refuse) v.event.reset();
  return v;
}

}  // namespace fleetgw::geofence
