#include "gateway/geofence/zone_enforcer.h"

#include <algorithm>

namespace fleetgw::geofence {

std::size_t ZoneEnforcer::level_index(const std::string& name) const {
  const auto it = std::find(config_.assist_levels.begin(), config_.assist_levels.end(), name);
  // A level outside the list (e.g. "walk", which still drives the motor) counts as the highest.
  if (it == config_.assist_levels.end()) return config_.assist_levels.size();
  return static_cast<std::size_t>(it - config_.assist_levels.begin());
}

std::optional<McWrite> ZoneEnforcer::next(const Demands& demands, const McView& mc, Micros now) {
  // The authority follows the demand even while the MC is busy: an operator's command computes
  // what it writes from it.
  speed().set_zone_demand(demands.speed_limit_kmh);
  if (outstanding_ || mc.busy) return std::nullopt;
  // Assist first: a no-ride fade is what keeps a rider from riding on, a limit only slows.
  auto write = next_assist(demands, mc, now);
  if (!write) write = next_speed(mc, now);
  outstanding_ = write;
  return write;
}

std::optional<McWrite> ZoneEnforcer::next_speed(const McView& mc, Micros now) {
  if (now < speed_retry_at_) return std::nullopt;
  const SpeedAuthority& authority = speed();
  // Nothing has ever asked for a limit: the MC's own setting is left alone.
  if (!authority.manages()) return std::nullopt;
  const auto target = authority.in_force();
  if (!target) return std::nullopt;
  // The MC's report is the truth; before one, the last confirmed write or the own limit.
  const std::optional<int> current =
      mc.speed_limit_kmh ? mc.speed_limit_kmh
                         : (applied_limit_ ? applied_limit_ : authority.own_limit());
  if (current == target) return std::nullopt;
  return McWrite{McWrite::Kind::kSpeedLimit, *target, {}};
}

std::optional<McWrite> ZoneEnforcer::next_assist(const Demands& demands, const McView& mc,
                                                 Micros now) {
  if (now < assist_retry_at_ || !mc.assist_level || config_.assist_levels.empty()) {
    return std::nullopt;
  }
  const std::size_t top = config_.assist_levels.size() - 1;
  const auto allowed = static_cast<std::size_t>(std::clamp(demands.assist_cap_percent, 0, 100) *
                                                static_cast<int>(top) / 100);
  const std::string& current = *mc.assist_level;
  if (demands.assist_cap_percent < 100 && level_index(current) > allowed) {
    if (!restore_level_) restore_level_ = current;
    return McWrite{McWrite::Kind::kAssistLevel, 0, config_.assist_levels[allowed]};
  }
  if (demands.assist_cap_percent >= 100 && restore_level_) {
    // Back to the rider's level, unless they chose another one meanwhile.
    if (written_level_ && current != *written_level_) {
      restore_level_.reset();
      written_level_.reset();
      return std::nullopt;
    }
    if (current == *restore_level_) {
      restore_level_.reset();
      written_level_.reset();
      return std::nullopt;
    }
    return McWrite{McWrite::Kind::kAssistLevel, 0, *restore_level_};
  }
  return std::nullopt;
}

void ZoneEnforcer::on_result(bool succeeded, Micros now) {
  if (!outstanding_) return;
  const McWrite w = std::move(*outstanding_);
  outstanding_.reset();
  if (w.kind == McWrite::Kind::kSpeedLimit) {
    if (!succeeded) {
      speed_retry_at_ = now + config_.retry_after;
      return;
    }
    applied_limit_ = w.speed_limit_kmh;
    return;
  }
  if (!succeeded) {
    assist_retry_at_ = now + config_.retry_after;
    return;
  }
  if (restore_level_ && w.assist_level == *restore_level_) {
    restore_level_.reset();
    written_level_.reset();
  } else {
    written_level_ = w.assist_level;
  }
}

}  // namespace fleetgw::geofence
