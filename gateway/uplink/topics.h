// MQTT topic names of one vehicle: <prefix>/<vehicle_id>/<leaf>.
//
// Contract: the constructor validates prefix and vehicle id (std::invalid_argument naming the
// field); the resulting names never contain wildcards or empty levels.
#pragma once

#include <string>
#include <string_view>

namespace fleetgw::uplink {

// True when `id` is a usable vehicle id: 1..64 characters of [A-Za-z0-9._-].
bool is_valid_vehicle_id(std::string_view id);
// True when `prefix` is non-empty, has no wildcard, NUL, empty level, leading or trailing '/'.
bool is_valid_topic_prefix(std::string_view prefix);

struct Topics {
  Topics(std::string_view prefix, std::string_view vehicle_id);

  std::string base;  // <prefix>/<vehicle_id>
  std::string telemetry, ride, fault, pack, lock, info, status, eviction, alarm, zone;
  std::string state;       // retained fleetgw.v1.VehicleState
  std::string cmd;         // subscribed
  std::string cmd_result;  // <base>/cmd/result
};

}  // namespace fleetgw::uplink
