// The facts of a status that the attention rules judge (status_report.h), as typed values.
//
// Why typed: the service judges its own status from the live components (the published
// fleetgw.v1.Status carries the verdict) without building or reading a JSON document, and
// `fleetgw status` judges the JSON document it received from the socket; both go through the
// one evaluate(const Health&). The service builds a Health once per status
// (runtime::make_status_health) and derives from it the document's judged keys and the
// protobuf's health fields, so the two always agree.
//
// Contract:
//  * A section that is nullopt is missing: the rules report it as "malformed" where the section
//    is required (bus, nodes, faults, locks, broker, disk, outbox). The service always fills
//    every required section; only a document from another process can lack one.
//  * health_from_json() reads a document defensively (missing or mistyped values take the
//    documented fallbacks, it never throws): the only place where the judged keys are read by
//    name.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fleetgw::status {

struct BusFacts {
  std::string interface;
  std::string state;  // can::controller_state_name(): "up", "down", "bus-off", ...
  std::string detail;
};

struct NodeFacts {
  std::string name;
  bool online = false;
  std::optional<double> last_heard_age_s;  // nullopt: never heard
};

struct FaultFacts {
  std::string node;
  std::optional<std::int64_t> code;  // nullopt: not known
  std::string name;
  std::string severity;  // "critical", "warning", ...
};

struct BrokerFacts {
  bool enabled = false;
  bool connected = false;
  std::string uri;                   // without user information
  std::string last_error;            // the connect failure's reason when known, else a count
  std::string last_publish_refusal;  // MQTT 5 refusals in force; "" = none
  std::uint64_t refused_records = 0;
};

struct StorageFacts {
  bool failing = false;
  std::string last_error;
  std::uint64_t failed_writes = 0;
  std::int64_t failing_since_us = 0;
  std::optional<double> failing_for_s;  // while failing and the start is known
  std::uint64_t configured_budget_bytes = 0;
  std::uint64_t effective_budget_bytes = 0;
  std::uint64_t dropped_records = 0;
};

struct DiskFacts {
  std::uint64_t used_bytes = 0;
  std::uint64_t budget_bytes = 0;  // the budget in force
};

struct OutboxFacts {
  std::uint64_t depth = 0;
  std::optional<double> oldest_unsent_age_s;  // nullopt: empty
};

struct GnssFacts {
  bool enabled = false;
  bool connected = false;
  std::string gpsd;
};

struct Health {
  std::optional<BusFacts> bus;
  std::optional<std::vector<NodeFacts>> nodes;
  std::optional<std::vector<FaultFacts>> faults;
  bool has_locks = true;  // the "locks" list is informational, but required
  std::optional<BrokerFacts> broker;
  std::optional<GnssFacts> gnss;        // optional section ([gnss] enabled)
  std::optional<StorageFacts> storage;  // optional section
  std::optional<DiskFacts> disk;
  std::optional<OutboxFacts> outbox;
};

// The judged facts of a status document (status_report.h's schema), read defensively.
Health health_from_json(const nlohmann::json& document);

}  // namespace fleetgw::status
