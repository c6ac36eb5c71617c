// DeviceInfoReporter: keeps the backend's view of the vehicle's nodes current by queuing a
// fleetgw.v1.DeviceInfo (topic `info`) at start and whenever a node's model information is
// first heard or changes.
//
// Contract:
//  * A node::RegistryObserver: on_model_info() (first sighting or change, as the registry
//    reports it) marks the report due; it is due once at construction too (the gateway's own
//    IoT node, so a vehicle whose bus is asleep still announces its gateway).
//  * take(registry) returns the serialized DeviceInfo when due (nullopt otherwise) and clears
//    the flag. Each report is complete: this gateway's node "iot" from its configured identity,
//    then every node whose model block was heard, in node-number order, named as on the wire
//    everywhere else (motinova::node_name: "mc", "bms", "lock1", ...). Bus text is untrusted:
//    bytes outside printable ASCII become '?'.
//  * Single-threaded; never reads a clock.
#pragma once

#include <optional>
#include <string>
#include <utility>

#include "gateway/node/node_config.h"
#include "gateway/node/node_registry.h"

namespace fleetgw::runtime {

class DeviceInfoReporter final : public node::RegistryObserver {
 public:
  explicit DeviceInfoReporter(node::Identity own) : own_(std::move(own)) {}

  void on_model_info(node::Node, const node::ModelInfo&, node::Micros) override { due_ = true; }

  bool due() const { return due_; }
  std::optional<std::string> take(const node::NodeRegistry& registry);

 private:
  node::Identity own_;
  bool due_ = true;
};

}  // namespace fleetgw::runtime
