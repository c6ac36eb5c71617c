#include "gateway/geofence/speed_authority.h"

#include <algorithm>

namespace fleetgw::geofence {
namespace {

std::optional<int> lower(std::optional<int> a, std::optional<int> b) {
  if (!a) return b;
  if (!b) return a;
  return std::min(*a, *b);
}

}  // namespace

void SpeedAuthority::set_operator_cap(std::optional<int> kmh) {
  cap_ = kmh;
  if (cap_) managed_ = true;
}

void SpeedAuthority::set_zone_demand(std::optional<int> kmh) {
  zone_demand_ = kmh;
  if (zone_demand_) managed_ = true;
}

void SpeedAuthority::on_zone_event(const ZoneEvent& e, std::string display_name) {
  if (e.kind != ZoneKind::kSlow) return;
  if (e.transition == Transition::kEnter) {
    slow_zones_[e.zone_id] = {std::move(display_name), e.speed_limit_kmh};
  } else if (e.transition == Transition::kExit) {
    slow_zones_.erase(e.zone_id);
  }
}

std::optional<int> SpeedAuthority::in_force_with_cap(std::optional<int> cap) const {
  return lower(lower(own_limit_, cap), zone_demand_);
}

std::string SpeedAuthority::explain_with_cap(std::optional<int> cap) const {
  std::string text = cap ? "capped at " + std::to_string(*cap) : std::string("no operator cap");
  const auto limit = in_force_with_cap(cap);
  if (!limit) return text + "; the MC's own limit in force";
  text += "; " + std::to_string(*limit) + " in force";
  const bool cap_decides = cap && *cap == *limit;
  if (zone_demand_ && *zone_demand_ == *limit && !cap_decides) {
    // The zone decides: name the lowest slow zone the bike is inside.
    const SlowZone* lowest = nullptr;
    for (const auto& [id, z] : slow_zones_) {
      if (lowest == nullptr || z.limit_kmh < lowest->limit_kmh) lowest = &z;
    }
    if (lowest == nullptr) {
      text += " (restoring after a slow zone)";
    } else {
      text += " inside '" + lowest->name + "'";
      if (lowest->limit_kmh < *limit) {
        text += " (slowing to " + std::to_string(lowest->limit_kmh) + ")";
      }
    }
  } else if (!cap_decides) {
    text += " (the bike's own limit)";
  }
  return text;
}

}  // namespace fleetgw::geofence
