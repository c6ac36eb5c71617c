// The status document of the running service (schema in gateway/status/status_report.h): what
// `fleetgw status` shows a technician. Built on demand from the live components; ages are
// computed here, on the service's own clock.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gateway/can/transport.h"
#include "gateway/config/config.h"
#include "gateway/geofence/zone_controller.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/uplink/uplink.h"
#include "storage/health.h"
#include "storage/store.h"

namespace fleetgw::runtime {

// Why the uplink cannot connect (UplinkStats' last_connect_error, last_connect_error_us and
// tls_failures; see CONTRACTS E): copied by the caller so this file does not depend on them.
struct UplinkFailure {
  std::string last_connect_error;          // "" = none since the last successful connect
  std::int64_t last_connect_error_us = 0;  // wall clock, us since epoch
  std::uint64_t tls_failures = 0;          // failed TLS handshakes since start
};

// The geofence section (Pipeline::geofence_status()): the bundle in force and what became of
// the bundles received.
struct GeofenceStatus {
  std::uint64_t version = 0;  // in force; 0 = none
  std::size_t zones = 0;
  std::size_t vertices = 0;
  std::string key_id;
  std::int64_t issued_at_us = 0;
  std::string bundle_file;
  std::vector<std::string> topics;  // subscribed (empty with [mqtt] disabled)
  geofence::BundleCounters counters;
  std::uint64_t dropped = 0;       // arrived while the uplink's queue of 4 was full (UplinkStats)
  std::string last_refusal_topic;  // where the latest refused bundle came from
  bool outside_operating_area = false;
};

struct StatusInputs {
  const config::Config& config;
  const GatewayCore& core;
  const can::Transport& transport;
  storage::Store& store;
  const uplink::Uplink* uplink;  // nullptr when [mqtt] is disabled
  Micros started;                // service start, on the bus timeline
  Micros now;                    // bus timeline (records carry bus time too)
  // Optional, so a caller that does not know them still builds a document (the sections then
  // show no failure). The pipeline passes Recorder::health() and the uplink's failure fields.
  std::optional<storage::StorageHealth> storage_health = std::nullopt;
  std::optional<UplinkFailure> uplink_failure = std::nullopt;
  const gnss::GnssFeed* gnss = nullptr;  // nullptr when [gnss] is disabled
  // Wall clock for the ages of wall-clock times (failing_since_us...); 0 = system_clock::now().
  Micros wall_now{0};
  // The ride in progress as the ride tracker would checkpoint it now (RideTracker::current);
  // nullopt when parked or unknown. Shown in the "vehicle" section.
  std::optional<storage::RideRow> open_ride = std::nullopt;
  // Parked mode (Pipeline::parked()): "mode" in the "vehicle" section is "parked" or "riding",
  // null before the first evaluation.
  std::optional<bool> parked = std::nullopt;
  // nullopt when [geofence] is disabled (no "geofence" section).
  std::optional<GeofenceStatus> geofence = std::nullopt;
  // The "campaigns" section (Pipeline::campaign_status(), issue 29); nullopt: none.
  std::optional<nlohmann::json> campaigns = std::nullopt;
  // The revocation list version in force (CommandService::revocation_version(), issue 28; 0:
  // none yet); nullopt without [command.root_keys] (no "revocations" section).
  std::optional<std::uint64_t> revocation_version = std::nullopt;
};

nlohmann::json make_status_json(const StatusInputs& in);

}  // namespace fleetgw::runtime
