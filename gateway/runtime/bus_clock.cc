#include "gateway/runtime/bus_clock.h"

#include <algorithm>

namespace fleetgw::runtime {

BusClock::Micros BusClock::now() const {
  switch (kind_) {
    case Kind::kSimulated:
      return last_frame_.count() > 0 ? last_frame_ : virtual_now_();
    case Kind::kReplay:
      return last_frame_;
    case Kind::kSystem:
      break;
  }
  return env_->wall_now();
}

BusClock::Micros BusClock::latest() const {
  return kind_ == Kind::kSimulated ? std::max(now(), virtual_now_()) : now();
}

std::optional<EngineTime> BusClock::to_engine(Micros bus) const {
  using D = EngineTime::duration;
  switch (kind_) {
    case Kind::kReplay:
      return std::nullopt;
    case Kind::kSimulated: {
      // Bus time -> engine time through the acceleration, on the simulator's own clock.
      const auto wait = std::chrono::duration_cast<D>(std::chrono::duration<double, std::micro>(
          static_cast<double>((bus - virtual_now_()).count()) / speed_));
      return env_->steady_now() + std::max<D>(wait, kMinSimWait);
    }
    case Kind::kSystem:
      break;
  }
  return env_->steady_now() + std::max<D>(bus - env_->wall_now(), D::zero());
}

}  // namespace fleetgw::runtime
