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
  }
  return "unknown";
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

ZoneEvent ZoneEngine::event_for(const Zone& zone, Transition t, Micros now,
                                const std::optional<gnss::Position>& where) const {
  ZoneEvent e;
  e.zone_id = zone.id;
  e.zone_name = zone.name;
  e.kind = zone.kind;
  e.transition = t;
  e.at = now;
  e.position = where;
  e.bundle_version = zones_ ? zones_->version : 0;
  e.speed_limit_kmh = zone.kind == ZoneKind::kSlow ? zone.speed_limit_kmh : 0;
  return e;
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
      } else if (states_[i].confirmed == Side::kInside) {
        // Its effects end with it: say so, as if the bike had left it.
        events.push_back(event_for(old, Transition::kExit, now, last_fix_));
      }
    }
  }
  zones_ = std::move(zones);
  states_ = std::move(next);
  update_targets(now);
}

Demands ZoneEngine::step(Micros now, const gnss::Position* fix, std::vector<ZoneEvent>& events) {
  if (fix == nullptr) {
    for (auto& s : states_) s.pending = Side::kUnknown;
    return demands(now);
  }
  last_fix_ = *fix;
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      const Zone& zone = zones_->zones[i];
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

void ZoneEngine::relocate(Micros now, const gnss::Position& fix, std::vector<ZoneEvent>& events) {
  if (!zones_) return;
  last_fix_ = fix;
  for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
    const Zone& zone = zones_->zones[i];
    State& s = states_[i];
    const Where w = zone.shape.locate(fix.lat_deg, fix.lon_deg, config_.margin_m);
    if (w == Where::kNearBoundary) continue;
    const Side side = w == Where::kInside ? Side::kInside : Side::kOutside;
    s.pending = Side::kUnknown;
    if (side == s.confirmed) continue;
    const Side before = std::exchange(s.confirmed, side);
    if (side == Side::kInside) {
      events.push_back(event_for(zone, Transition::kEnter, now, fix));
    } else if (before == Side::kInside) {
      events.push_back(event_for(zone, Transition::kExit, now, fix));
    }
  }
  update_targets(now);
}

void ZoneEngine::update_targets(Micros now) {
  double speed = config_.unrestricted_kmh;
  bool no_ride = false;
  if (zones_) {
    for (std::size_t i = 0; i < zones_->zones.size(); ++i) {
      if (states_[i].confirmed != Side::kInside) continue;
      const Zone& zone = zones_->zones[i];
      if (zone.kind == ZoneKind::kSlow) speed = std::min<double>(speed, zone.speed_limit_kmh);
      if (zone.kind == ZoneKind::kNoRide) no_ride = true;
    }
  }
  speed_.retarget(speed, now,
                  speed < speed_.value(now) ? config_.speed_ramp : config_.restore_ramp);
  assist_.retarget(no_ride ? 0.0 : 100.0, now,
                   no_ride ? config_.assist_fade : config_.restore_ramp);
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
      const Zone& zone = zones_->zones[i];
      const Side side = states_[i].confirmed;
      if (zone.kind == ZoneKind::kOperatingArea) {
        any_area = true;
        inside_area = inside_area || side == Side::kInside;
        every_area_known = every_area_known && side != Side::kUnknown;
      }
      if (zone.kind == ZoneKind::kNoParking && side == Side::kInside) d.in_no_parking_zone = true;
    }
    d.outside_operating_area = any_area && !inside_area && every_area_known;
  }
  return d;
}

std::optional<Micros> ZoneEngine::next_change(Micros now) const {
  const auto a = speed_.next_step(now);
  const auto b = assist_.next_step(now);
  if (a && b) return std::min(*a, *b);
  return a ? a : b;
}

ParkingVerdict ZoneEngine::parking(const gnss::Position* fix, bool ride_ending, Micros now) const {
  ParkingVerdict v;
  if (fix == nullptr || !zones_) return v;
  const Zone* near = nullptr;
  for (const Zone& zone : zones_->zones) {
    if (zone.kind != ZoneKind::kNoParking) continue;
    const Where w = zone.shape.locate(fix->lat_deg, fix->lon_deg, config_.margin_m);
    if (w == Where::kOutside) continue;
    v.in_no_parking_zone = true;
    if (w == Where::kInside && ride_ending && config_.refuse_ride_ending_locks) {
      v.refuse = true;
      v.event = event_for(zone, Transition::kLockRefused, now, *fix);
      return v;
    }
    if (near == nullptr) near = &zone;
  }
  if (near != nullptr) v.event = event_for(*near, Transition::kLockedInNoParking, now, *fix);
  return v;
}

}  // namespace fleetgw::geofence
