// The shipped `fleetgw run` as a child process against a real mosquitto, and an operator that
// signs commands and waits for their results over MQTT (one Paho client in this process: two
// in one process share Paho's network threads, which adds tens of ms per direction). Used by
// the service tests and by bench/bench_service.cc.
#pragma once

#include <mqtt/async_client.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/uplink/tcp_nodelay.h"
#include "tests/support/process.h"

namespace fleetgw::testing {

using SteadyClock = std::chrono::steady_clock;

// Signs lock commands and waits for the CommandResult bound to each command id.
class CommandOperator {
 public:
  CommandOperator(const std::string& broker_uri, std::string vehicle,
                  command::Ed25519PrivateKey key, std::string key_id)
      : client_(broker_uri, "operator-" + vehicle, mqtt::create_options(MQTTVERSION_3_1_1)),
        vehicle_(std::move(vehicle)),
        key_(std::move(key)),
        key_id_(std::move(key_id)) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      {
        std::lock_guard l(mu_);
        inbox_.push_back(std::move(m));
      }
      cv_.notify_one();
    });
    mqtt::connect_options co;
    co.set_clean_session(true);
    client_.connect(co)->wait();
    client_.subscribe("fleet/v1/" + vehicle_ + "/cmd/result", 1)->wait();
    // As `fleetgw command` does after connecting.
    if (const auto port = uplink::broker_port(broker_uri))
      uplink::enable_tcp_nodelay_to_port(*port);
  }
  ~CommandOperator() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(1));
    } catch (...) {
    }
  }

  struct Outcome {
    bool answered = false;
    v1::CommandResultCode result = v1::COMMAND_RESULT_CODE_UNSPECIFIED;
    std::string reason;
    std::chrono::microseconds round_trip{0};
  };

  // Publishes one signed command and waits up to `timeout` for its result.
  // `signer` overrides the key (e.g. an untrusted one), signed under the same key id.
  Outcome send(const std::string& id, std::string_view lock, std::string_view action,
               std::chrono::milliseconds timeout,
               const command::Ed25519PrivateKey* signer = nullptr) {
    const auto wall = now();
    return send(
        *command::make_command(vehicle_, lock, action, wall, wall + std::chrono::seconds(60), id),
        timeout, signer);
  }
  // An MC action (command::make_mc_command: "speed_limit" with "15", "headlight" with "on", ...).
  Outcome send_mc(const std::string& id, std::string_view action, std::string_view value,
                  std::chrono::milliseconds timeout) {
    const auto wall = now();
    return send(*command::make_mc_command(vehicle_, action, value, wall,
                                          wall + std::chrono::seconds(60), id),
                timeout);
  }

  // Signs and publishes `c`, then waits up to `timeout` for the result bound to its id.
  Outcome send(const v1::Command& c, std::chrono::milliseconds timeout,
               const command::Ed25519PrivateKey* signer = nullptr) {
    using namespace std::chrono;
    const std::string& id = c.command_id();
    const std::string payload = command::sign_command(c, signer ? *signer : key_, key_id_);
    Outcome out;
    const auto t0 = SteadyClock::now();
    const auto deadline = t0 + timeout;
    client_.publish("fleet/v1/" + vehicle_ + "/cmd", payload.data(), payload.size(), 1, false);
    std::unique_lock l(mu_);
    while (!out.answered) {
      if (!cv_.wait_until(l, deadline, [this] { return !inbox_.empty(); })) break;
      const auto m = std::move(inbox_.front());
      inbox_.pop_front();
      v1::Envelope env;
      const auto& p = m->get_payload_ref();
      if (env.ParseFromArray(p.data(), static_cast<int>(p.size())) && env.has_command_result() &&
          env.command_result().command_id() == id) {
        out.answered = true;
        out.result = env.command_result().result();
        out.reason = env.command_result().reason();
      }
    }
    out.round_trip = duration_cast<microseconds>(SteadyClock::now() - t0);
    return out;
  }

 private:
  mqtt::async_client client_;
  std::string vehicle_;
  command::Ed25519PrivateKey key_;
  std::string key_id_;
  static motinova::Micros now() {
    return std::chrono::duration_cast<motinova::Micros>(
        std::chrono::system_clock::now().time_since_epoch());
  }

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<mqtt::const_message_ptr> inbox_;
};

}  // namespace fleetgw::testing
