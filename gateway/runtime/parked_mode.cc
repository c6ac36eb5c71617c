#include "gateway/runtime/parked_mode.h"

#include <utility>

namespace fleetgw::runtime {

bool ParkedMode::update(const ParkedView& view, Micros now) {
  const bool calm = config_.enabled && view.locked && !view.moving && !view.alarm;
  if (!calm) {
    calm_since_.reset();
  } else if (!calm_since_) {
    calm_since_ = now;
  }
  const bool parked = calm_since_ && now - *calm_since_ >= config_.settle;
  const bool changed = parked_ != parked;
  parked_ = parked;
  return changed;
}

Micros ParkedMode::next_event() const {
  if (!calm_since_ || parked_.value_or(false)) return Micros::max();
  return *calm_since_ + config_.settle;
}

ParkedController::ParkedController(ParkedConfig config, const domain::DomainTrackers& trackers,
                                   GatewayCore& core, std::function<void(bool)> on_change)
    : mode_(config), trackers_(trackers), core_(core), on_change_(std::move(on_change)) {}

void ParkedController::tick(Micros now) {
  const domain::AlarmTracker& alarms = trackers_.alarms();
  const LiveState& live = core_.live();
  ParkedView view;
  view.locked = alarms.locked();
  view.moving = alarms.moving_while_locked() ||
                (live.speed_kmh && *live.speed_kmh > mode_.config().still_kmh);
  view.alarm = alarms.active();
  if (!mode_.update(view, now)) return;
  ++changes_;
  const bool parked = mode_.parked().value_or(false);
  std::optional<node::ParkedPolling> polling;
  if (parked)
    polling = node::ParkedPolling{mode_.config().poll_period, mode_.config().stale_poll_period};
  core_.node().poller().set_parked(polling, now);
  if (on_change_) on_change_(parked);
}

}  // namespace fleetgw::runtime
