// Test support for the command-burst tests: a backend that publishes raw payloads on a vehicle's
// `cmd` topic as fast as Paho takes them (QoS 1, no waiting between them) and records every
// CommandResult on `cmd/result`; and the payloads such a backend or an attacker sends.
#pragma once

#include <mqtt/async_client.h>

#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/signing.h"
#include "tests/support/wait.h"

namespace fleetgw::command::testing {

class BurstClient {
 public:
  BurstClient(const std::string& broker_uri, std::string vehicle)
      : client_(broker_uri, "burst-" + vehicle, mqtt::create_options(MQTTVERSION_3_1_1, 10000)),
        vehicle_(std::move(vehicle)) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      v1::Envelope env;
      const auto& p = m->get_payload_ref();
      if (!env.ParseFromArray(p.data(), static_cast<int>(p.size())) || !env.has_command_result()) {
        return;
      }
      std::lock_guard l(mu_);
      results_.push_back(env.command_result());
    });
    mqtt::connect_options co;
    co.set_clean_session(true);
    co.set_max_inflight(1000);  // the whole burst in flight at once
    client_.connect(co)->wait();
    client_.subscribe("fleet/v1/" + vehicle_ + "/cmd/result", 1)->wait();
  }
  ~BurstClient() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(1));
    } catch (...) {
    }
  }
  BurstClient(const BurstClient&) = delete;
  BurstClient& operator=(const BurstClient&) = delete;

  // Publishes every payload back to back, then waits for the broker's PUBACKs.
  void publish(const std::vector<std::string>& payloads) {
    std::vector<mqtt::delivery_token_ptr> tokens;
    tokens.reserve(payloads.size());
    for (const auto& p : payloads) {
      tokens.push_back(client_.publish(topic(), p.data(), p.size(), 1, false));
    }
    for (auto& t : tokens) t->wait_for(std::chrono::seconds(10));
  }
  std::string topic() const { return "fleet/v1/" + vehicle_ + "/cmd"; }

  std::vector<v1::CommandResult> results() const {
    std::lock_guard l(mu_);
    return results_;
  }
  // Results bound to what was sent (signing.h result_answers), by command id.
  std::map<std::string, std::vector<v1::CommandResult>> answers(
      const std::map<std::string, SentCommand>& sent) const {
    std::map<std::string, std::vector<v1::CommandResult>> out;
    for (const auto& r : results()) {
      const auto it = sent.find(r.command_id());
      if (it != sent.end() && result_answers(r, it->first, it->second)) {
        out[r.command_id()].push_back(r);
      }
    }
    return out;
  }
  // Waits until every command in `sent` has at least one bound answer.
  bool wait_for_answers(const std::map<std::string, SentCommand>& sent,
                        std::chrono::seconds limit) const {
    return fleetgw::testing::wait_until([&] { return answers(sent).size() == sent.size(); }, limit);
  }

 private:
  mqtt::async_client client_;
  std::string vehicle_;
  mutable std::mutex mu_;
  std::vector<v1::CommandResult> results_;
};

// A well-formed command under a trusted key id with a zeroed signature: what anyone who can
// publish on `cmd` can send (issue 24's junk).
inline std::string junk_command(const v1::Command& c, std::string_view key_id) {
  v1::SignedCommand s;
  s.set_command(c.SerializeAsString());
  s.set_key_id(std::string(key_id));
  s.set_signature(std::string(64, '\0'));
  return s.SerializeAsString();
}

inline std::string reason_code_of(const v1::CommandResult& r) {
  return r.reason().substr(0, r.reason().find(':'));
}

}  // namespace fleetgw::command::testing
