// The status of the running service, in its two forms: the document of the status socket
// (schema in gateway/status/status_report.h; what `fleetgw status` shows a technician) and the
// retained fleetgw.v1.Status the uplink publishes. Both are built on demand from the live
// components' typed values, neither from the other; ages are computed here, on the service's
// own clock.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "fleetgw/v1/status.pb.h"
#include "gateway/can/transport.h"
#include "gateway/config/config.h"
#include "gateway/geofence/zone_controller.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/status/status_health.h"
#include "gateway/uplink/uplink.h"
#include "storage/health.h"
#include "storage/store.h"

namespace fleetgw::runtime {

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
  // The uplink's stats (Uplink::stats(), read once per status); nullopt when [mqtt] is
  // disabled. Its outbox figures are the document's and the Status's outbox.
  std::optional<uplink::UplinkStats> uplink;
  Micros started;  // service start, on the bus timeline
  Micros now;      // bus timeline (records carry bus time too)
  // Optional, so a caller that does not know it still builds a document (the section then
  // shows no failure). The pipeline passes Recorder::health().
  std::optional<storage::StorageHealth> storage_health = std::nullopt;
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
  // The published Status's bus_state (Pipeline::bus_state()); not part of the document, whose
  // "bus" section has the controller's own state.
  fleetgw::v1::BusState bus_state = fleetgw::v1::BUS_STATE_UNSPECIFIED;
};

// The judged facts (status_health.h), derived once from the typed inputs: make_status_json()
// writes the document's judged keys from them and make_status_message() the Status's health
// and verdict, so the two agree by construction.
status::Health make_status_health(const StatusInputs& in);
// The document of the status socket (`fleetgw status`; schema in status_report.h).
nlohmann::json make_status_json(const StatusInputs& in);
// The retained fleetgw.v1.Status the uplink publishes, built directly from the typed inputs:
// firmware, bus state, outbox, the uplink's fields (uplink/uplink_status.h), storage health and
// the attention verdict. The connection's own fields (state, connection, connected_at_us) are
// the uplink's to stamp.
fleetgw::v1::Status make_status_message(const StatusInputs& in);

}  // namespace fleetgw::runtime
