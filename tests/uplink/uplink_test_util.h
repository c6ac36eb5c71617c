// Helpers for the uplink integration tests: a Paho subscriber that records every message, a
// loop that drives an Uplink until a condition holds, and record builders.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <mqtt/async_client.h>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/uplink.h"
#include "gateway/uplink/uplink_status.h"

namespace fleetgw::testing {

inline motinova::Micros wall_now() {
  return std::chrono::duration_cast<motinova::Micros>(
      std::chrono::system_clock::now().time_since_epoch());
}

struct Received {
  std::string topic;
  std::string payload;
  int qos = 0;
  bool retained = false;
};

// Subscribes to `filter` and records every message. TLS when `ssl` is given.
class Subscriber {
 public:
  // persistent: keep the session (clean_session=false) and reconnect automatically, so that
  // messages queued by the broker during a subscriber outage are not lost.
  Subscriber(const std::string& uri, const std::string& filter, const std::string& client_id,
             std::optional<mqtt::ssl_options> ssl = std::nullopt, bool persistent = false)
      : client_(uri, client_id) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      std::lock_guard lock(mutex_);
      messages_.push_back({m->get_topic(), m->get_payload_str(), m->get_qos(), m->is_retained()});
      cv_.notify_all();
    });
    mqtt::connect_options opts;
    opts.set_clean_session(!persistent);
    if (persistent)
      opts.set_automatic_reconnect(std::chrono::milliseconds(50), std::chrono::milliseconds(200));
    if (ssl) opts.set_ssl(*ssl);
    client_.connect(opts)->wait();
    client_.subscribe(filter, 1)->wait();
  }
  ~Subscriber() {
    try {
      if (client_.is_connected()) client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (...) {
    }
  }

  std::vector<Received> messages() const {
    std::lock_guard lock(mutex_);
    return messages_;
  }
  void clear() {
    std::lock_guard lock(mutex_);
    messages_.clear();
  }
  // Waits until pred(messages) holds or the timeout passes; returns pred's last value.
  bool wait_until(const std::function<bool(const std::vector<Received>&)>& pred,
                  std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return pred(messages_); });
  }
  mqtt::async_client& client() { return client_; }

 private:
  mqtt::async_client client_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Received> messages_;
};

// Polls the uplink (on this thread, as its owner would) until `done` or the timeout.
// Plays the owner's status route (the pipeline's status stage, runtime/status_stage.h): when
// the uplink wants a status, one is built from its stats and handed over. `decorate` adds what
// a test wants the owner's status to carry. True when one was handed.
inline bool hand_status(uplink::Uplink& up,
                        const std::function<void(v1::Status&)>& decorate = nullptr) {
  if (!up.status_wanted()) return false;
  const uplink::UplinkStats stats = up.stats();
  v1::Status s;
  s.set_firmware_version("test-1.2.3");
  s.set_outbox_depth(stats.outbox_depth);
  s.set_oldest_unsent_created_at_us(stats.oldest_unsent_created_us);
  uplink::fill_status(s, stats);
  if (decorate) decorate(s);
  up.set_status(std::move(s));
  return true;
}

inline bool drive(uplink::Uplink& up, const std::function<bool()>& done,
                  std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    up.poll(wall_now());
    // As the engine's settle does: the status handed is published in the same turn.
    if (hand_status(up)) up.poll(wall_now());
    if (done()) return true;
    up.wait_for_events(std::chrono::milliseconds(5));
  }
  up.poll(wall_now());
  return done();
}

inline std::string telemetry_payload(std::uint32_t speed_dkmh) {
  v1::TelemetrySample s;
  s.set_sampled_at_us(wall_now().count());
  s.set_speed_dkmh(speed_dkmh);
  s.set_voltage_mv(48'123);
  s.set_current_ma(-1500);
  s.set_soc_pct(87);
  s.set_odo_m(123'456'700);
  return s.SerializeAsString();
}

inline std::string fault_payload(std::uint32_t bit) {
  v1::FaultEvent f;
  f.set_node("mc");
  f.set_bit(bit);
  f.set_name("over_current_protect");
  f.set_severity(v1::FAULT_SEVERITY_CRITICAL);
  f.set_kind(v1::FAULT_EVENT_KIND_RAISED);
  f.set_occurrences(1);
  return f.SerializeAsString();
}

inline std::string ride_payload(const std::string& id) {
  v1::RideRecord r;
  r.set_ride_id(id);
  r.set_distance_odo_m(4200);
  r.set_energy_mwh(96'000);
  return r.SerializeAsString();
}

// All outbox sequence numbers carried by the received Envelopes (telemetry: per sample).
inline std::vector<std::uint64_t> received_sequences(const std::vector<Received>& msgs,
                                                     const std::string& vehicle) {
  std::vector<std::uint64_t> out;
  for (const auto& m : msgs) {
    v1::Envelope env;
    if (!env.ParseFromString(m.payload) || env.vehicle_id() != vehicle) continue;
    if (env.has_telemetry()) {
      for (const auto& s : env.telemetry().samples()) out.push_back(s.sequence());
    } else if (env.sequence() != 0) {
      out.push_back(env.sequence());
    }
  }
  return out;
}

// The last Status among what `sub` received (default-constructed when there was none).
inline v1::Status last_status(Subscriber& sub) {
  v1::Status s;
  for (const auto& m : sub.messages()) {
    v1::Envelope env;
    if (env.ParseFromString(m.payload) && env.has_status()) s = env.status();
  }
  return s;
}

inline uplink::UplinkConfig plain_config(const std::string& uri, const std::string& vehicle) {
  uplink::UplinkConfig c;
  c.broker_uri = uri;
  c.vehicle_id = vehicle;
  c.firmware_version = "test-1.2.3";
  c.reconnect_min = std::chrono::milliseconds(50);
  c.reconnect_max = std::chrono::milliseconds(400);
  c.jitter_seed = 42;
  c.live_telemetry_qos = 1;  // tests that need "no loss" everywhere
  c.telemetry_batch_max_delay = std::chrono::milliseconds(20);
  c.connect_timeout = std::chrono::seconds(3);
  c.resend_after = std::chrono::seconds(3);
  return c;
}

}  // namespace fleetgw::testing
