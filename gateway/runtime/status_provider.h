// The status document of the running service (schema in gateway/status/status_report.h): what
// `fleetgw status` shows a technician. Built on demand from the live components; ages are
// computed here, on the service's own clock.
#pragma once

#include <nlohmann/json.hpp>

#include "gateway/can/transport.h"
#include "gateway/config/config.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/uplink/uplink.h"
#include "storage/store.h"

namespace fleetgw::runtime {

struct StatusInputs {
  const config::Config& config;
  const GatewayCore& core;
  const can::Transport& transport;
  storage::Store& store;
  const uplink::Uplink* uplink;  // nullptr when [mqtt] is disabled
  Micros started;                // service start, on the bus timeline
  Micros now;                    // bus timeline (records carry bus time too)
};

nlohmann::json make_status_json(const StatusInputs& in);

}  // namespace fleetgw::runtime
