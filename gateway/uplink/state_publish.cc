// Uplink: the retained vehicle state (fleetgw.v1.VehicleState on <prefix>/<vehicle>/state).
// See uplink.h (set_vehicle_state) for the contract and docs/uplink.md ("Last-known state") for
// how `online` here relates to the retained Status and the last will.
#include <spdlog/spdlog.h>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/uplink_impl.h"

namespace fleetgw::uplink {

void Uplink::set_vehicle_state(std::string body) {
  impl_->vehicle_state = std::move(body);
  impl_->vehicle_state_due = true;
}

void Uplink::set_telemetry_batch_delay(std::optional<std::chrono::milliseconds> delay) {
  impl_->batch_delay = delay.value_or(impl_->config.telemetry_batch_max_delay);
}

void Uplink::Impl::publish_vehicle_state(Micros now, bool online) {
  v1::Envelope env;
  fill_header(env, header(0, now.count()));
  // The body comes from the owner; it is parsed (not spliced) because `online` is ours to set.
  if (!env.mutable_state()->ParseFromString(vehicle_state)) {
    spdlog::error("uplink: vehicle state ({} bytes) does not decode; not published",
                  vehicle_state.size());
    vehicle_state.clear();
    vehicle_state_due = false;
    return;
  }
  env.mutable_state()->set_online(online);
  // QoS 1 and retained whatever [mqtt] qos says: a dashboard must find it.
  if (publish(topics.state, env.SerializeAsString(), 1, true, {})) vehicle_state_due = false;
}

}  // namespace fleetgw::uplink
