// Internal to the uplink: what Paho's threads (and the connect diagnosis thread) hand to poll().
//
// Contract: events are plain values, nothing refers to Paho objects. EventQueue is the only
// state shared between those threads and the owner's thread: push() is thread-safe and calls
// the wake-up hook after every event; take() moves all queued events out. The number of queued
// commands (per lane: authenticated, unauthenticated, busy notices) and zone bundles is tracked
// in atomics so the Paho thread can bound each without scanning the queue.
// Listeners tag tokens with our own integer id (never a pointer), so a late completion of a
// publish already given up on is simply ignored. Reason codes are taken only when they are a
// real MQTT 5 code (0..0xFE): Paho marks 3.1.1 tokens with MQTTPP_V3_CODE (0xFF), which MQTT 5
// does not define.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <variant>

#include <mqtt/async_client.h>

namespace fleetgw::uplink::detail {

struct ConnectDone {
  std::uint64_t attempt;
  bool ok;
  int rc;
  std::string message;
  int reason = 0;  // MQTT 5 CONNACK reason code (0 under 3.1.1)
};
struct ConnectionLost {
  std::string cause;
};
struct PublishDone {
  std::uint64_t id;
  bool ok;
  int rc;
  std::string message;
  // MQTT 5 PUBACK reason code; >= 0x80 = the broker refused the message (mqtt5.h). 0 under
  // 3.1.1 and for failures that are not the broker's answer (connection lost...).
  int reason = 0;
};
struct SubscribeDone {
  std::uint64_t id;  // 0 = cmd, n = zone_topics[n - 1]
  bool ok;
  int rc;
};
struct CommandArrived {
  std::string payload;
  // The owner's authenticator found a trusted key's valid signature (always true without an
  // authenticator). Each lane has its own bound (uplink.h "Commands").
  bool authenticated = true;
};
// An authenticated command the full queue could not take: only what its busy answer needs.
struct CommandBusy {
  std::string command_id;
  std::string command_sha256;
};
// Why a command payload was dropped unanswered (UplinkStats counts each class).
enum class CommandDropClass : std::uint8_t {
  kOversized,
  kUndecodable,
  kUnauthenticated,
  kQueueFull
};
struct CommandDropped {
  CommandDropClass drop_class;
  std::string reason;
  bool large = false;  // a payload worth returning the heap to the system after
};
// A message on a zone-bundle topic: its payload, or only its size when it was over the limit
// (never copied).
struct ZoneBundleArrived {
  std::string topic;
  std::string payload;
  std::size_t oversized_bytes = 0;  // > 0: refused unread
};
struct ZoneBundleDropped {
  std::string topic;
  std::string reason;
};
// The diagnosis of failed connect attempt `attempt` (connect_diagnosis.h).
struct ConnectDiagnosed {
  std::uint64_t attempt;
  std::string reason;
};
using Event = std::variant<ConnectDone, ConnectionLost, PublishDone, SubscribeDone, CommandArrived,
                           CommandBusy, CommandDropped, ZoneBundleArrived, ZoneBundleDropped,
                           ConnectDiagnosed>;

class EventQueue {
 public:
  void push(Event e) {
    {
      std::lock_guard lock(mutex_);
      if (const auto* c = std::get_if<CommandArrived>(&e)) {
        ++(c->authenticated ? queued_commands_ : queued_unauthenticated_);
      }
      if (std::holds_alternative<CommandBusy>(e)) ++queued_busy_;
      if (std::holds_alternative<ZoneBundleArrived>(e)) ++queued_zone_bundles_;
      events_.push_back(std::move(e));
    }
    cv_.notify_one();
    if (wakeup_) wakeup_();
  }
  std::deque<Event> take() {
    std::lock_guard lock(mutex_);
    return std::exchange(events_, {});
  }
  bool wait(std::chrono::milliseconds max_wait) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, max_wait, [&] { return !events_.empty(); });
  }
  // Authenticated commands queued or waiting for take_commands(); the owner releases them with
  // commands_taken(). The same for unauthenticated payloads and for busy notices
  // (take_busy_commands()).
  std::size_t queued_commands() const { return queued_commands_.load(); }
  void commands_taken(std::size_t n) { queued_commands_ -= n; }
  std::size_t queued_unauthenticated() const { return queued_unauthenticated_.load(); }
  void unauthenticated_taken(std::size_t n) { queued_unauthenticated_ -= n; }
  std::size_t queued_busy() const { return queued_busy_.load(); }
  void busy_taken(std::size_t n) { queued_busy_ -= n; }
  // The same for zone bundles (take_zone_bundles()).
  std::size_t queued_zone_bundles() const { return queued_zone_bundles_.load(); }
  void zone_bundles_taken(std::size_t n) { queued_zone_bundles_ -= n; }

  // Set before the client starts; read-only afterwards, so no lock is needed to call it.
  std::function<void()> wakeup_;

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Event> events_;
  std::atomic<std::size_t> queued_commands_{0};
  std::atomic<std::size_t> queued_unauthenticated_{0};
  std::atomic<std::size_t> queued_busy_{0};
  std::atomic<std::size_t> queued_zone_bundles_{0};
};

inline void* to_context(std::uint64_t id) {
  return reinterpret_cast<void*>(static_cast<std::uintptr_t>(id));
}
inline std::uint64_t from_context(const mqtt::token& tok) {
  return static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(tok.get_user_context()));
}

inline int mqtt5_reason(const mqtt::token& tok) {
  const int code = tok.get_reason_code();
  return code >= 0 && code < 0xFF ? code : 0;
}

inline std::string token_error(const mqtt::token& tok) {
  std::string msg = "rc " + std::to_string(tok.get_return_code());
  const std::string text = mqtt::exception::error_str(tok.get_return_code());
  if (!text.empty()) msg += " (" + text + ")";
  return msg;
}

class ConnectListener final : public mqtt::iaction_listener {
 public:
  explicit ConnectListener(EventQueue& q) : q_(q) {}
  void on_success(const mqtt::token& tok) override {
    q_.push(ConnectDone{from_context(tok), true, 0, {}});
  }
  void on_failure(const mqtt::token& tok) override {
    q_.push(ConnectDone{from_context(tok), false, tok.get_return_code(), token_error(tok),
                        mqtt5_reason(tok)});
  }

 private:
  EventQueue& q_;
};

class PublishListener final : public mqtt::iaction_listener {
 public:
  explicit PublishListener(EventQueue& q) : q_(q) {}
  void on_success(const mqtt::token& tok) override {
    q_.push(PublishDone{from_context(tok), true, 0, {}});
  }
  void on_failure(const mqtt::token& tok) override {
    q_.push(PublishDone{from_context(tok), false, tok.get_return_code(), token_error(tok),
                        mqtt5_reason(tok)});
  }

 private:
  EventQueue& q_;
};

class SubscribeListener final : public mqtt::iaction_listener {
 public:
  explicit SubscribeListener(EventQueue& q) : q_(q) {}
  // MQTT 5: a SUBACK reason code >= 0x80 (e.g. 0x87 not authorized) is a refusal too.
  void on_success(const mqtt::token& tok) override {
    const int reason = mqtt5_reason(tok);
    q_.push(SubscribeDone{from_context(tok), reason < 0x80, reason});
  }
  void on_failure(const mqtt::token& tok) override {
    q_.push(SubscribeDone{from_context(tok), false, tok.get_return_code()});
  }

 private:
  EventQueue& q_;
};

}  // namespace fleetgw::uplink::detail
