// GatewayCore: the clock-free heart of `fleetgw run`. One CAN frame in, through the
// reassembler and the decoder, out to the IoT node's behaviour, the live state and every
// attached listener (domain trackers, recorders). The same object runs under the asio service
// (real or accelerated time) and inside the simulator's VirtualBus (virtual time), which is what
// makes the service testable end to end in milliseconds.
//
// Contract:
//  * Single-threaded; every entry point takes `now`. on_can_frame() and tick() never block.
//  * tick() must be called when now >= next_event() (the pipeline arms its one timer for it;
//    on_can_frame() ticks by itself when a frame's timestamp passes it). Partial messages are
//    expired there too. next_event() is the node's own next deadline (exact: retries, polls,
//    broadcasts, timeouts; node::IotNode::next_event) or the listeners' next tick, whichever
//    comes first. Listeners (trackers, commands: timeouts of seconds) are ticked every
//    kTickInterval of bus time while frames flow and every kIdleTickInterval on a silent bus,
//    so an idle gateway wakes only for the node's own schedule.
//  * Echoes: what the node transmits is shown to the listeners too (the bus does not echo a
//    sender's own frames, and the trackers need the gateway's LOCK/UNLOCK/SHUTDOWN broadcasts),
//    but never from inside the send: echoes are queued and delivered after the frame or tick
//    being handled, in transmit order. A caller that makes the node send from outside the core
//    (the command service) calls deliver_echoes() when that call has returned. So a listener is
//    never re-entered and always sees a frame before the gateway's reaction to it.
//  * An echo is the message as the bus carries it, decoded once per distinct message the node
//    sends (OwnMessages, own_messages.h), not once per transmission: the frame is encoded once,
//    for the bus, and a message sent again is shown from what was decoded the first time
//    (CoreStats::echoes, echo_decodes).
//  * Listeners and the FrameSender must outlive the core.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "gateway/config/config.h"
#include "gateway/node/frame_sender.h"
#include "gateway/node/iot_node.h"
#include "gateway/runtime/live_state.h"
#include "gateway/runtime/own_messages.h"
#include "motinova/codec.h"
#include "motinova/reassembler.h"

namespace fleetgw::runtime {

using motinova::Micros;

class MessageListener {
 public:
  virtual ~MessageListener() = default;
  virtual void on_message(const motinova::DecodedMessage& message, Micros now) = 0;
  virtual void tick(Micros /*now*/) {}
};

// Maps the [node] section of the configuration onto the node's own config.
node::NodeConfig make_node_config(const config::Config& config);

struct CoreStats {
  uint64_t messages = 0;
  uint64_t unknown_messages = 0;
  uint64_t length_mismatches = 0;
  uint64_t echoes = 0;        // own messages shown to the listeners
  uint64_t echo_decodes = 0;  // of those, decoded (first sight of a distinct message)
};

class GatewayCore final : private motinova::FrameSink {
  // What the node transmits is shown to the listeners as well: the bus does not echo a
  // sender's own frames, and the trackers need the gateway's LOCK/UNLOCK/SHUTDOWN broadcasts.
  // Queues every frame the node transmits successfully for deliver_echoes().
  class EchoSender final : public node::FrameSender {
   public:
    EchoSender(node::FrameSender& inner, GatewayCore& core) : inner_(inner), core_(core) {}
    bool send(const motinova::AppFrame& frame) override;

   private:
    node::FrameSender& inner_;
    GatewayCore& core_;
  };

 public:
  static constexpr Micros kTickInterval{50'000};
  static constexpr Micros kIdleTickInterval{1'000'000};

  GatewayCore(const config::Config& config, node::FrameSender& sender, node::NodeHooks hooks = {});
  ~GatewayCore() override;

  void add_listener(MessageListener& listener) { listeners_.push_back(&listener); }

  void start(Micros now);
  void on_can_frame(const motinova::CanFrame& frame, Micros timestamp);
  void tick(Micros now);
  Micros next_event() const;
  // The node's own next deadline, and when a silent bus needs a listener tick.
  Micros node_deadline() const;
  Micros idle_deadline() const { return last_tick_ + kIdleTickInterval; }
  // The node is waiting for the bus on someone's behalf (a lock job, the shutdown procedure):
  // frames should reach the core without batching delay.
  bool latency_critical() const { return node_->latency_critical(); }
  // Delivers queued echoes (see the contract); a no-op when called from inside a delivery.
  void deliver_echoes();
  bool echoes_pending() const { return !echoes_.empty(); }

  // Mutable access may start something with an earlier deadline: next_event() recomputes.
  node::IotNode& node() {
    node_due_stale_ = true;
    return *node_;
  }
  const node::IotNode& node() const { return *node_; }
  const LiveState& live() const { return live_; }
  const motinova::ReassemblerStats& bus_stats() const { return reassembler_.stats(); }
  const CoreStats& stats() const { return stats_; }
  const motinova::DecodeOptions& options() const { return options_; }

 private:
  void on_frame(const motinova::AppFrame& frame, Micros ts) override;
  void on_error(const motinova::ReassemblyErrorEvent& error) override;

  motinova::DecodeOptions options_;
  motinova::Reassembler reassembler_;
  EchoSender echo_;
  OwnMessages own_;  // what the node transmits, decoded once per distinct message
  std::vector<const OwnMessages::Entry*> echoes_;  // transmitted, not yet shown to the listeners
  bool delivering_echoes_ = false;
  Micros now_{0};
  std::unique_ptr<node::IotNode> node_;
  motinova::DecodedMessage decoded_;
  LiveState live_;
  CoreStats stats_;
  std::vector<MessageListener*> listeners_;
  Micros listeners_due_{Micros::max()};  // next listener tick
  Micros last_tick_{0};
  bool traffic_since_tick_ = false;
  // node_->next_event(), cached: recomputed after everything that can move it earlier.
  mutable Micros node_due_{Micros::max()};
  mutable bool node_due_stale_ = true;
  Micros last_error_log_{0};
  uint64_t errors_since_log_ = 0;
};

}  // namespace fleetgw::runtime
