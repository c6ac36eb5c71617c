// A scripted fake bus for the IoT-node tests: a FrameSender that records what the node sends
// (with the virtual time of each send), builders for peer frames made with motinova::MessageWriter,
// and a driver that feeds frames through the real wire path (encode → segment → reassemble →
// decode) at chosen virtual times and ticks the node in fixed steps.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "gateway/node/iot_node.h"
#include "gateway/node/messages.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"

namespace fleetgw::node::test {

using namespace std::chrono_literals;
using motinova::AppFrame;
using motinova::Micros;
using motinova::Node;

// Records every frame the node sends, stamped with the virtual time.
class RecordingSender final : public FrameSender {
 public:
  struct Sent {
    AppFrame frame;
    Micros at;
  };
  explicit RecordingSender(const Micros& clock) : clock_(clock) {}

  bool send(const AppFrame& frame) override {
    sent.push_back({frame, clock_});
    return accept;
  }

  // Sends matching (CAN ID, function), optionally only those at or after `since`.
  std::vector<Sent> matching(uint16_t can_id, uint8_t function, Micros since = Micros{-1}) const {
    std::vector<Sent> out;
    for (const Sent& s : sent) {
      if (s.frame.can_id == can_id && s.frame.function == function && s.at >= since) {
        out.push_back(s);
      }
    }
    return out;
  }
  std::size_t count(uint16_t can_id, uint8_t function) const {
    return matching(can_id, function).size();
  }
  std::vector<Sent> on_id(uint16_t can_id) const {
    std::vector<Sent> out;
    for (const Sent& s : sent) {
      if (s.frame.can_id == can_id) out.push_back(s);
    }
    return out;
  }

  std::vector<Sent> sent;
  bool accept = true;

 private:
  const Micros& clock_;
};

// Peer frames, built from the catalogue like a real peer would build them.
inline const motinova::MessageDesc& desc(std::string_view name, uint16_t can_id) {
  const motinova::MessageDesc* d = motinova::Catalogue::standard().find(name, can_id);
  if (d == nullptr) {
    throw std::runtime_error("test: no catalogue message '" + std::string(name) + "' on ID " +
                             std::to_string(can_id));
  }
  return *d;
}

inline const motinova::DecodeOptions& default_options() {
  static const motinova::DecodeOptions options;
  return options;
}

inline AppFrame peer_keyword(std::string_view name, uint16_t can_id) {
  return motinova::MessageWriter(desc(name, can_id), default_options()).frame();
}
inline AppFrame peer_fault_word(std::string_view name, uint16_t can_id, uint32_t word) {
  return motinova::MessageWriter(desc(name, can_id), default_options()).raw("raw", word).frame();
}
inline AppFrame peer_model_info(uint16_t can_id, std::string_view model, std::string_view serial) {
  return motinova::MessageWriter(desc("device_info", can_id), default_options())
      .text("model", model)
      .text("serial", serial)
      .text("hw", "HW2.1")
      .text("fw", "V1.2.3_20240501")
      .frame();
}
inline AppFrame lock_status(int k, uint8_t state) {
  const uint16_t id = ids::lock_broadcast_id(k);
  return motinova::MessageWriter(desc("lock_status", id), default_options())
      .raw("voltage_v", 12000)
      .raw("state", state)
      .frame();
}
inline AppFrame bms_status() {
  return motinova::MessageWriter(desc("bms_status", ids::kBmsBroadcast), default_options())
      .raw("soc_pct", 80)
      .frame();
}

// Drives an IotNode on a virtual timeline.
class FakeBus : private motinova::FrameSink {
 public:
  // Called for every frame the node sends (after it was recorded): lets a test script peers.
  using Responder = std::function<void(const AppFrame& sent, FakeBus& bus)>;

  explicit FakeBus(NodeConfig config, NodeHooks hooks = {}) : sender(now) {
    node =
        std::make_unique<IotNode>(std::move(config), default_options(), sender, std::move(hooks));
  }

  void start() {
    node->start(now);
    respond();
  }

  // Feeds `frame` as received at the current time, through encode/segment/reassemble/decode.
  void deliver(const AppFrame& frame) {
    for (const motinova::CanFrame& can : motinova::segment(frame, motinova::CrcOrder::kBig)) {
      reassembler_.push(can, now, *this);
    }
    respond();
  }
  // Advances virtual time to `until`, ticking every `step` (deliveries scheduled with at() run at
  // their time).
  void run_until(Micros until, Micros step = 10ms) {
    while (now < until) {
      now = std::min(now + step, until);
      run_scheduled();
      node->tick(now);
      respond();
    }
  }
  void run_for(Micros d, Micros step = 10ms) { run_until(now + d, step); }
  // Advances to `until` ticking ONLY when the node asks to (IotNode::next_event), as the
  // runtime does; returns the number of ticks. Fails the test if a tick leaves the node asking
  // for the same instant again (it would spin).
  int run_by_deadline(Micros until) {
    int ticks = 0;
    while (true) {
      Micros next = node->next_event();
      for (const auto& s : scheduled_) next = std::min(next, s.first);
      if (next > until) break;
      now = std::max(now, next);
      run_scheduled();
      if (now >= node->next_event()) {
        node->tick(now);
        ++ticks;
        EXPECT_GT(node->next_event(), now) << "the node asks for the instant it just ticked";
        if (node->next_event() <= now) break;
      }
      respond();
    }
    now = until;
    return ticks;
  }
  // Schedules a delivery at virtual time `t`.
  void at(Micros t, AppFrame frame) { scheduled_.push_back({t, std::move(frame)}); }

  Micros now{1'700'000'000'000'000};  // an epoch-like origin: nothing may assume time starts at 0
  RecordingSender sender;
  std::unique_ptr<IotNode> node;
  Responder responder;
  std::vector<std::string> reassembly_errors;

 private:
  void on_frame(const AppFrame& frame, Micros ts) override {
    motinova::DecodedMessage msg;
    motinova::decode(frame, motinova::Catalogue::standard(), default_options(), msg);
    node->on_frame(frame, msg, ts);
  }
  void on_error(const motinova::ReassemblyErrorEvent& e) override {
    reassembly_errors.emplace_back(motinova::reassembly_error_name(e.kind));
  }
  void run_scheduled() {
    for (std::size_t i = 0; i < scheduled_.size();) {
      if (scheduled_[i].first <= now) {
        AppFrame f = scheduled_[i].second;
        scheduled_.erase(scheduled_.begin() + static_cast<std::ptrdiff_t>(i));
        deliver(f);
      } else {
        ++i;
      }
    }
  }
  void respond() {
    while (responded_ < sender.sent.size()) {
      const AppFrame f = sender.sent[responded_++].frame;
      if (responder) responder(f, *this);
    }
  }

  motinova::Reassembler reassembler_;
  std::vector<std::pair<Micros, AppFrame>> scheduled_;
  std::size_t responded_ = 0;
};

// A config with no poll table and no fitted locks: tests add exactly what they exercise.
inline NodeConfig quiet_config() {
  NodeConfig c;
  c.identity.serial = "SN0001";
  c.identity.firmware_date = "20250301";
  c.poll_table = std::vector<PollEntry>{};
  return c;
}

}  // namespace fleetgw::node::test
