// StateStage (state_stage.h): the retained vehicle state and parked mode, moved out of the
// Pipeline (issue 26).
#include "gateway/runtime/state_stage.h"

#include <spdlog/spdlog.h>

#include <utility>

#include "gateway/runtime/stages.h"

namespace fleetgw::runtime {

ParkedConfig make_parked_config(const config::Config& c) {
  ParkedConfig p;
  p.enabled = c.parked.enabled;
  p.settle = Micros(int64_t{c.parked.settle_s} * 1'000'000);
  p.poll_period = Micros(int64_t{c.parked.poll_interval_ms} * 1000);
  p.stale_poll_period = Micros(int64_t{c.parked.stale_poll_ms} * 1000);
  return p;
}

StateStageConfig make_state_stage_config(const config::Config& c) {
  StateStageConfig s;
  s.min_interval = std::chrono::milliseconds(c.mqtt.enabled ? c.mqtt.state_interval_ms : 0);
  s.min_move_m = c.mqtt.state_min_move_m;
  s.parked = make_parked_config(c);
  s.parked_batch_delay = std::chrono::milliseconds(c.parked.telemetry_batch_ms);
  return s;
}

StateStage::StateStage(StateStageConfig config, StateSources sources, Env& env,
                       std::function<void()> signal)
    : sources_(sources),
      env_(env),
      signal_(std::move(signal)),
      parked_batch_delay_(config.parked_batch_delay),
      throttle_(config.min_interval),
      position_filter_(config.min_move_m),
      parked_(config.parked, sources.trackers, sources.core,
              [this](bool parked) { on_parked(parked); }) {}

void StateStage::on_position(std::optional<gnss::Fix> position) {
  position_ = std::move(position);
  throttle_.touch();
}

void StateStage::set_outside_operating_area(bool outside) {
  if (outside == outside_operating_area_) return;
  outside_operating_area_ = outside;
  throttle_.touch();
}

void StateStage::on_parked(bool parked) {
  throttle_.touch();
  spdlog::info("vehicle {}", parked ? "parked: polling and uplink at the parked rates"
                                    : "riding: polling and uplink at the riding rates");
  rates =
      Rates{.parked = parked,
            .telemetry_batch_delay = parked ? std::optional(parked_batch_delay_) : std::nullopt};
  if (signal_) signal_();
}

StageRun StateStage::run(EngineTime now) {
  // A parked/riding change (heard in the core's tick) waits for the route like the state.
  const std::size_t waiting = rates ? 1 : 0;
  if (!throttle_.due(now)) return {.produced = waiting, .status = {}};
  return {.produced = waiting + (check(now) ? 1u : 0u), .status = {}};
}

bool StateStage::check_now() {
  if (!throttle_.enabled()) return false;
  throttle_.touch();
  return check(env_.steady_now());
}

bool StateStage::check(EngineTime now) {
  VehicleStateInputs in;
  in.live = &sources_.core.live();
  in.active_alarms = sources_.trackers.alarms().active_kinds();
  in.outside_operating_area = outside_operating_area_;
  in.parked = parked();
  in.bus_state = bus_state(sources_.transport, sources_.clock,
                           sources_.core.node().registry().config().offline_timeout);
  in.now = sources_.clock.now();
  in.position = position_filter_.comparable(position_);
  const std::optional<gnss::Fix> compared = in.position;
  if (!throttle_.offer(build_vehicle_state(in, false), now)) return false;
  position_filter_.handed_over(compared);
  in.position = position_;
  state = build_vehicle_state(in);
  return true;
}

}  // namespace fleetgw::runtime
