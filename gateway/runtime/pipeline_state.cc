// Pipeline: the wiring of the retained vehicle state and parked mode. The policy lives in the
// StateStage (state_stage.h); here it is built, its parked listener added to the core, and its
// outputs moved: the state handed to the uplink (published in this settle), the parked/riding
// rates applied to the uplink's telemetry batches.
#include "gateway/runtime/pipeline.h"

namespace fleetgw::runtime {

void Pipeline::start_state(const config::Config& config) {
  state_stage_ = std::make_unique<StateStage>(make_state_stage_config(config),
                                              StateSources{.core = core_,
                                                           .trackers = recorder_->trackers(),
                                                           .clock = clock_,
                                                           .transport = *bus_.transport},
                                              env_, [this] { request_settle(); });
  core_.add_listener(state_stage_->parked_listener());
}

bool Pipeline::route_state() {
  StateStage& s = *state_stage_;
  if (s.rates) {
    if (uplink_) {
      uplink_->set_telemetry_batch_delay(s.rates->telemetry_batch_delay);
      uplink_stage_->stored();  // a batch held back while parked may be due now
    }
    s.rates.reset();
  }
  if (s.state) {
    if (uplink_) {
      uplink_->set_vehicle_state(std::move(*s.state));
      uplink_stage_->stored();
    }
    s.state.reset();
  }
  return false;  // the uplink runs later in this round
}

}  // namespace fleetgw::runtime
