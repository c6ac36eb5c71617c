// Pipeline: the status of the running service (runtime/status_provider.h). Its two forms are
// built from the same live components: the document of the status socket on request
// (status_document()), and the retained fleetgw.v1.Status as a value the status stage builds
// and the route hands to the uplink (status_stage.h), when the uplink asks for one (a new
// connection, changed refusals), the bus state changed, or its refresh is due.
#include "gateway/runtime/pipeline.h"

namespace fleetgw::runtime {

StatusInputs Pipeline::status_inputs() const {
  StatusInputs in{config_, core_, *bus_.transport, store_, std::nullopt, start_, bus_now()};
  if (uplink_) in.uplink = uplink_->stats();
  in.storage_health = recorder_->health();
  in.gnss = gnss_.get();
  in.wall_now = env_.wall_now();
  in.open_ride = recorder_->trackers().rides().current(bus_now());
  in.parked = parked();
  in.geofence = geofence_status();
  in.campaigns = campaign_status();
  if (!config_.command.root_keys.empty()) in.revocation_version = revocation_version();
  in.bus_state = bus_state();
  return in;
}

nlohmann::json Pipeline::status_document() const {
  return make_status_json(status_inputs());
}

fleetgw::v1::Status Pipeline::status_message() {
  const StatusInputs in = status_inputs();
  status_bus_state_ = in.bus_state;
  return make_status_message(in);
}

void Pipeline::add_status_stage() {
  status_stage_ = std::make_unique<StatusStage>(
      [this] { return status_message(); },
      std::chrono::milliseconds(config_.mqtt.status_interval_ms), engine_);
  engine_.add(*status_stage_, [this] {
    if (!status_stage_->status) return false;
    uplink_->set_status(std::move(*status_stage_->status));
    status_stage_->status.reset();
    uplink_stage_->stored();  // published at the uplink's next poll, in this settle
    return true;
  });
}

void Pipeline::want_status() {
  if (uplink_->status_wanted() || bus_state() != status_bus_state_) status_stage_->want();
}

}  // namespace fleetgw::runtime
