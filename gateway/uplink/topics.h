// MQTT topic names of one vehicle: <prefix>/<vehicle_id>/<leaf>, and the fleet-wide ones below
// <prefix>/.
//
// Contract: kTopicTable is THE list of topics the gateway uses: every topic it publishes to and
// every topic it subscribes to, each once, with its direction. Topics is built from it, and the
// broker ACL shipped in deploy/mosquitto/acl is checked against it (acl_patterns(), tested in
// tests/uplink/test_topic_acl.cc), so a new topic cannot ship without the broker granting it.
// The constructor validates prefix and vehicle id (std::invalid_argument naming the field); the
// resulting names never contain wildcards or empty levels. A record kind's leaf and name come
// from the record-kind table (proto/record_kinds.h), so they cannot disagree with the outbox,
// the Envelope or the ingest.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "proto/record_kinds.h"

namespace fleetgw::uplink {

// True when `id` is a usable vehicle id: 1..64 characters of [A-Za-z0-9._-].
bool is_valid_vehicle_id(std::string_view id);
// True when `prefix` is non-empty, has no wildcard, NUL, empty level, leading or trailing '/'.
bool is_valid_topic_prefix(std::string_view prefix);

struct Topics {
  Topics(std::string_view prefix, std::string_view vehicle_id);

  std::string base;  // <prefix>/<vehicle_id>
  std::string telemetry, ride, fault, pack, lock, info, status, eviction, alarm, zone;
  std::string state;            // retained fleetgw.v1.VehicleState
  std::string cmd;              // subscribed
  std::string command_result;   // <base>/cmd/result (the historic leaf: a wire contract)
  std::string zones;            // subscribed: this vehicle's zone bundles (<base>/zones)
  std::string fleet_zones;      // subscribed: the fleet-wide zone bundles (<prefix>/zones)
  std::string campaign;         // campaign samples (issue 29)
  std::string campaigns;        // subscribed: this vehicle's campaigns (<base>/campaigns)
  std::string fleet_campaigns;  // subscribed: the fleet-wide campaigns (<prefix>/campaigns)
  std::string revocations;      // subscribed: the root's revocation list (issue 28), retained
};

enum class TopicDirection { kPublish, kSubscribe };

struct TopicSpec {
  std::string_view leaf;         // below <prefix>/<vehicle_id>/, or below <prefix>/ if fleet_wide
  TopicDirection direction;      // what the gateway does with it (the broker must grant it)
  bool fleet_wide;               // shared by every vehicle: <prefix>/<leaf>
  std::string Topics::*member;   // where Topics keeps the full name
  std::string_view record_kind;  // the record kind published there (its stored name); "" if none
};

// A record kind's topic: leaf and name from the record-kind table (proto/record_kinds.h).
constexpr TopicSpec record_topic(records::RecordKind kind, std::string Topics::*member) {
  return {records::spec(kind).topic_leaf, TopicDirection::kPublish, false, member,
          records::stored_name(kind)};
}

inline constexpr std::array<TopicSpec, 19> kTopicTable{{
    record_topic(records::RecordKind::kTelemetry, &Topics::telemetry),
    record_topic(records::RecordKind::kRide, &Topics::ride),
    record_topic(records::RecordKind::kFault, &Topics::fault),
    record_topic(records::RecordKind::kPack, &Topics::pack),
    record_topic(records::RecordKind::kLock, &Topics::lock),
    record_topic(records::RecordKind::kInfo, &Topics::info),
    record_topic(records::RecordKind::kStatus, &Topics::status),  // + the last will
    record_topic(records::RecordKind::kEvictionReport, &Topics::eviction),
    record_topic(records::RecordKind::kAlarm, &Topics::alarm),
    record_topic(records::RecordKind::kZone, &Topics::zone),
    {"state", TopicDirection::kPublish, false, &Topics::state, "state"},  // retained, no record
    record_topic(records::RecordKind::kCommandResult, &Topics::command_result),  // "cmd/result"
    {"cmd", TopicDirection::kSubscribe, false, &Topics::cmd, ""},
    {"zones", TopicDirection::kSubscribe, false, &Topics::zones, ""},
    {"zones", TopicDirection::kSubscribe, true, &Topics::fleet_zones, ""},
    record_topic(records::RecordKind::kCampaign, &Topics::campaign),
    {"campaigns", TopicDirection::kSubscribe, false, &Topics::campaigns, ""},
    {"campaigns", TopicDirection::kSubscribe, true, &Topics::fleet_campaigns, ""},
    {"revocations", TopicDirection::kSubscribe, false, &Topics::revocations, ""},
}};

// The kTopicTable entry a record kind is published on (every kind has exactly one; tested).
constexpr const TopicSpec* record_kind_topic(records::RecordKind kind) {
  for (const auto& t : kTopicTable) {
    if (t.record_kind == records::stored_name(kind)) return &t;
  }
  return nullptr;
}

// The entry whose full name in `topics` is `*topic` (compared by address: Topics' own members);
// nullptr for any other string.
const TopicSpec* find_topic(const Topics& topics, const std::string* topic);

// The mosquitto ACL lines a vehicle needs, one per kTopicTable entry, e.g.
// "pattern write fleet/v1/%u/telemetry" and "pattern read fleet/v1/zones" (%u = the vehicle id,
// the certificate CN with use_identity_as_username). `prefix` is uplink.topic_prefix.
std::vector<std::string> acl_patterns(std::string_view prefix);

}  // namespace fleetgw::uplink
