// Test support: what a backend sees of one vehicle on a real broker: every Envelope published
// under fleet/v1/<vehicle>/, decoded, with the topic it came on.
//
// Contract:
//  * The constructor connects to `uri` (clean session, a client id unique in this process) and
//    has subscribed fleet/v1/<vehicle>/# at QoS 1 when it returns, so nothing published after
//    that is missed; mqtt::exception when the broker cannot be reached.
//  * Payloads that do not decode as an Envelope are ignored; the tests assert what did arrive.
//  * Messages arrive on Paho's thread: every accessor returns a copy taken under the lock.
//  * Header-only, so fleetgw_test_support needs neither Paho nor the protobuf schema: a target
//    including this links PahoMqttCpp::paho-mqttpp3 and fleetgw_proto.
#pragma once

#include <mqtt/async_client.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::testing {

class VehicleWatcher {
 public:
  template <typename M>
  struct Received {
    std::string topic;
    M message;
  };

  VehicleWatcher(const std::string& uri, const std::string& vehicle)
      : client_(uri, "vehicle-watch-" + std::to_string(getpid()) + "-" +
                         std::to_string(next_client_number())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      if (!e.ParseFromString(m->get_payload())) return;
      std::lock_guard lock(mutex_);
      if (e.has_zone()) zones_.push_back({m->get_topic(), e.zone()});
      if (e.has_alarm()) alarms_.push_back({m->get_topic(), e.alarm()});
      if (e.has_state()) state_ = e.state();
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + vehicle + "/#", 1)->wait();
  }
  ~VehicleWatcher() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (...) {  // a destructor never throws: the broker may be gone already
    }
  }
  VehicleWatcher(const VehicleWatcher&) = delete;
  VehicleWatcher& operator=(const VehicleWatcher&) = delete;

  std::vector<Received<fleetgw::v1::ZoneEvent>> zones() {
    std::lock_guard lock(mutex_);
    return zones_;
  }
  std::vector<Received<fleetgw::v1::Alarm>> alarms() {
    std::lock_guard lock(mutex_);
    return alarms_;
  }
  // The latest VehicleState (the retained one first), if any came.
  std::optional<fleetgw::v1::VehicleState> state() {
    std::lock_guard lock(mutex_);
    return state_;
  }

  // "<zone id> <transition number>" in arrival order, for one readable comparison.
  std::vector<std::string> zone_log() {
    std::vector<std::string> out;
    for (const auto& z : zones()) {
      out.push_back(z.message.zone_id() + " " + std::to_string(z.message.transition()));
    }
    return out;
  }
  bool has_zone(const std::string& id, fleetgw::v1::ZoneTransition t) {
    const auto all = zones();
    return std::any_of(all.begin(), all.end(), [&](const auto& z) {
      return z.message.zone_id() == id && z.message.transition() == t;
    });
  }
  bool has_alarm(fleetgw::v1::AlarmKind kind, fleetgw::v1::AlarmTransition t) {
    const auto all = alarms();
    return std::any_of(all.begin(), all.end(), [&](const auto& a) {
      return a.message.kind() == kind && a.message.transition() == t;
    });
  }
  // Whether the latest VehicleState lists `kind` among its active alarms.
  bool state_lists(fleetgw::v1::AlarmKind kind) {
    const auto s = state();
    if (!s) return false;
    const auto& a = s->active_alarms();
    return std::find(a.begin(), a.end(), kind) != a.end();
  }

 private:
  // Two watchers in one process must not share a client id (the broker would drop one).
  static int next_client_number() {
    static std::atomic<int> n{0};
    return ++n;
  }

  mqtt::async_client client_;
  std::mutex mutex_;
  std::vector<Received<fleetgw::v1::ZoneEvent>> zones_;
  std::vector<Received<fleetgw::v1::Alarm>> alarms_;
  std::optional<fleetgw::v1::VehicleState> state_;
};

}  // namespace fleetgw::testing
