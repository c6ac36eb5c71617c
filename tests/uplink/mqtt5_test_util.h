// Helpers for the MQTT 5 tests of the uplink and of `fleetgw command`: a Paho subscriber that
// speaks MQTT 5 and records, besides topic and payload, the properties fleetgw sets (content
// type, the schema user property, message expiry), and the ACL texts of the refusal tests.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <mqtt/async_client.h>

namespace fleetgw::testing {

struct Received5 {
  std::string topic;
  std::string payload;
  bool retained = false;
  std::string content_type;              // empty: no CONTENT_TYPE property
  std::string schema;                    // user property "schema"; empty: absent
  std::string will_delay_s;              // user property "will_delay_s"; empty: absent
  std::optional<std::int64_t> expiry_s;  // MESSAGE_EXPIRY_INTERVAL as the broker forwarded it
  std::chrono::steady_clock::time_point at;
};

// An MQTT 5 subscriber. persistent: clean start off, a 300 s session and automatic reconnects, so
// it keeps its subscription across a broker restart (with broker persistence) and receives
// what was queued for it while it was away.
class Subscriber5 {
 public:
  Subscriber5(const std::string& uri, const std::string& filter, const std::string& client_id,
              bool persistent = false)
      : client_(uri, client_id, mqtt::create_options(MQTTVERSION_5)) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) { record(*m); });
    auto opts = mqtt::connect_options_builder()
                    .mqtt_version(MQTTVERSION_5)
                    .clean_start(!persistent)
                    .finalize();
    if (persistent) {
      opts.set_properties(mqtt::properties{{mqtt::property::SESSION_EXPIRY_INTERVAL, 300}});
      opts.set_automatic_reconnect(std::chrono::milliseconds(50), std::chrono::milliseconds(200));
    }
    client_.connect(opts)->wait();
    client_.subscribe(filter, 1)->wait();
  }
  ~Subscriber5() {
    try {
      if (client_.is_connected()) client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (...) {
    }
  }

  std::vector<Received5> messages() const {
    std::lock_guard lock(mutex_);
    return messages_;
  }
  // Waits until pred(messages) holds or the timeout passes; returns pred's last value.
  bool wait_until(const std::function<bool(const std::vector<Received5>&)>& pred,
                  std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return pred(messages_); });
  }
  mqtt::async_client& client() { return client_; }

 private:
  void record(const mqtt::message& m) {
    Received5 r{m.get_topic(),
                m.get_payload_str(),
                m.is_retained(),
                {},
                {},
                {},
                {},
                std::chrono::steady_clock::now()};
    const auto& props = m.get_properties();
    if (props.contains(mqtt::property::CONTENT_TYPE)) {
      r.content_type = mqtt::get<std::string>(props, mqtt::property::CONTENT_TYPE);
    }
    for (std::size_t i = 0; i < props.count(mqtt::property::USER_PROPERTY); ++i) {
      const auto kv = mqtt::get<mqtt::string_pair>(props, mqtt::property::USER_PROPERTY, i);
      if (std::get<0>(kv) == "schema") r.schema = std::get<1>(kv);
      if (std::get<0>(kv) == "will_delay_s") r.will_delay_s = std::get<1>(kv);
    }
    if (props.contains(mqtt::property::MESSAGE_EXPIRY_INTERVAL)) {
      r.expiry_s = mqtt::get<std::int32_t>(props, mqtt::property::MESSAGE_EXPIRY_INTERVAL);
    }
    std::lock_guard lock(mutex_);
    messages_.push_back(std::move(r));
    cv_.notify_all();
  }

  mqtt::async_client client_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Received5> messages_;
};

}  // namespace fleetgw::testing
