// Pipeline: the retained last-known vehicle state (gateway/runtime/vehicle_state.h). Built from
// the live state, the alarm tracker, the GNSS fix and the parked/riding mode when the throttle
// says a check is due, and handed to the uplink only when it changed.
#include <spdlog/spdlog.h>

#include "gateway/runtime/pipeline.h"

namespace fleetgw::runtime {

ParkedConfig make_parked_config(const config::Config& c) {
  ParkedConfig p;
  p.enabled = c.parked.enabled;
  p.settle = Micros(int64_t{c.parked.settle_s} * 1'000'000);
  p.poll_period = Micros(int64_t{c.parked.poll_interval_ms} * 1000);
  p.stale_poll_period = Micros(int64_t{c.parked.stale_poll_ms} * 1000);
  return p;
}

void Pipeline::attach_parked_feed() {
  parked_ = std::make_unique<ParkedController>(parked_config_, recorder_->trackers(), core_,
                                               [this](bool parked) {
                                                 state_throttle_.touch();
                                                 apply_parked_rates(parked);
                                               });
  core_.add_listener(*parked_);
}

void Pipeline::apply_parked_rates(bool parked) {
  if (uplink_) {
    uplink_->set_telemetry_batch_delay(
        parked ? std::optional<std::chrono::milliseconds>(parked_batch_delay_) : std::nullopt);
    uplink_stage_->stored();  // a batch held back while parked may be due now
  }
  spdlog::info("vehicle {}", parked ? "parked: polling and uplink at the parked rates"
                                    : "riding: polling and uplink at the riding rates");
}

bool Pipeline::update_vehicle_state() {
  VehicleStateInputs in;
  in.live = &core_.live();
  const domain::DomainTrackers& trackers = recorder_->trackers();
  in.active_alarms = trackers.alarms().active_kinds();
  in.outside_operating_area = outside_operating_area_;
  std::optional<gnss::Fix> position;
  if (gnss_) position = gnss_->state().current(gnss_->wall_now());
  in.parked = parked();
  in.bus_state = bus_state();
  in.now = bus_now();
  in.position = state_position_.comparable(position);
  const std::optional<gnss::Fix> compared = in.position;
  if (!state_throttle_.offer(build_vehicle_state(in, false), env_.steady_now())) return false;
  state_position_.handed_over(compared);
  in.position = position;
  uplink_->set_vehicle_state(build_vehicle_state(in));
  uplink_stage_->stored();
  return true;
}

StageRun Pipeline::StateStage::run(EngineTime now) {
  if (!p_.state_throttle_.due(now)) return {};
  return {.produced = p_.update_vehicle_state() ? 1u : 0u, .status = {}};
}

}  // namespace fleetgw::runtime
