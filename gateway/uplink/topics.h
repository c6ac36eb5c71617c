// MQTT topic names of one vehicle: <prefix>/<vehicle_id>/<leaf>, and the fleet-wide ones below
// <prefix>/.
//
// Contract: kTopicTable is THE list of topics the gateway uses: every topic it publishes to and
// every topic it subscribes to, each once, with its direction. Topics is built from it, and the
// broker ACL shipped in deploy/mosquitto/acl is checked against it (acl_patterns(), tested in
// tests/uplink/test_topic_acl.cc), so a new topic cannot ship without the broker granting it.
// The constructor validates prefix and vehicle id (std::invalid_argument naming the field); the
// resulting names never contain wildcards or empty levels.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::uplink {

// True when `id` is a usable vehicle id: 1..64 characters of [A-Za-z0-9._-].
bool is_valid_vehicle_id(std::string_view id);
// True when `prefix` is non-empty, has no wildcard, NUL, empty level, leading or trailing '/'.
bool is_valid_topic_prefix(std::string_view prefix);

struct Topics {
  Topics(std::string_view prefix, std::string_view vehicle_id);

  std::string base;  // <prefix>/<vehicle_id>
  std::string telemetry, ride, fault, pack, lock, info, status, eviction, alarm, zone;
  std::string state;        // retained fleetgw.v1.VehicleState
  std::string cmd;          // subscribed
  std::string cmd_result;   // <base>/cmd/result
  std::string zones;        // subscribed: this vehicle's zone bundles (<base>/zones)
  std::string fleet_zones;  // subscribed: the fleet-wide zone bundles (<prefix>/zones)
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
  std::string_view record_kind;  // the outbox kind published there (outbox_source.h); "" if none
};

// The record kinds are spelled out (not taken from outbox_source.h) to keep this header free of
// the outbox; test_topic_acl.cc checks every route of envelope_writer.cc lands on its own entry.
inline constexpr std::array<TopicSpec, 19> kTopicTable{{
    {"telemetry", TopicDirection::kPublish, false, &Topics::telemetry, "telemetry"},
    {"ride", TopicDirection::kPublish, false, &Topics::ride, "ride"},
    {"fault", TopicDirection::kPublish, false, &Topics::fault, "fault"},
    {"pack", TopicDirection::kPublish, false, &Topics::pack, "pack"},
    {"lock", TopicDirection::kPublish, false, &Topics::lock, "lock"},
    {"info", TopicDirection::kPublish, false, &Topics::info, "info"},
    {"status", TopicDirection::kPublish, false, &Topics::status, "status"},  // + the last will
    {"eviction", TopicDirection::kPublish, false, &Topics::eviction, "eviction"},
    {"alarm", TopicDirection::kPublish, false, &Topics::alarm, "alarm"},
    {"zone", TopicDirection::kPublish, false, &Topics::zone, "zone"},
    {"state", TopicDirection::kPublish, false, &Topics::state, "state"},  // retained
    {"cmd/result", TopicDirection::kPublish, false, &Topics::cmd_result, "cmd_result"},
    {"cmd", TopicDirection::kSubscribe, false, &Topics::cmd, ""},
    {"zones", TopicDirection::kSubscribe, false, &Topics::zones, ""},
    {"zones", TopicDirection::kSubscribe, true, &Topics::fleet_zones, ""},
    {"campaign", TopicDirection::kPublish, false, &Topics::campaign, "campaign"},
    {"campaigns", TopicDirection::kSubscribe, false, &Topics::campaigns, ""},
    {"campaigns", TopicDirection::kSubscribe, true, &Topics::fleet_campaigns, ""},
    {"revocations", TopicDirection::kSubscribe, false, &Topics::revocations, ""},
}};

// The entry whose full name in `topics` is `*topic` (compared by address: Topics' own members);
// nullptr for any other string.
const TopicSpec* find_topic(const Topics& topics, const std::string* topic);

// The mosquitto ACL lines a vehicle needs, one per kTopicTable entry, e.g.
// "pattern write fleet/v1/%u/telemetry" and "pattern read fleet/v1/zones" (%u = the vehicle id,
// the certificate CN with use_identity_as_username). `prefix` is uplink.topic_prefix.
std::vector<std::string> acl_patterns(std::string_view prefix);

}  // namespace fleetgw::uplink
