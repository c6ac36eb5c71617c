// IotNode: the gateway's behaviour as MOTINOVA node 6 (spec §3.5, §3.7, §3.8, Appendix A),
// tying together the node registry, the poller, the own broadcasts, the lock actuator and the
// shutdown procedure over one RequestEngine and one FrameSender.
//
// Contract:
//  * Clock-free: the runtime calls start(now) once, on_frame() for every received application
//    frame (after decode()), and tick(now) when now >= next_event(); every API call takes `now`.
//    next_event() is the earliest deadline of every part (request retry/timeout, poll due,
//    broadcast or event repeat, lock job step, shutdown timeout, node offline, fault word
//    stale), so the spec's timing is exact without a periodic tick; ticking more often is
//    harmless. It may move earlier after on_frame() or any call that starts something.
//    Everything happens synchronously inside these calls on the caller's thread (not
//    thread-safe; the runtime serialises calls on its io_context).
//  * Peer SHUTDOWN (OBC 0x730/0x1008, BMS 0x720/0x1308) is answered with READY on 0x760/0x1405
//    within the same on_frame() call, after the `on_peer_shutdown` hook ran (the hook is where
//    the runtime saves its state: READY means "ready to lose power"). READY is then repeated per
//    BroadcastPolicy::event_transmissions (default 3 copies, 200 ms apart).
//  * Registry observers added through registry() see node online/offline and fault-word changes;
//    when a node comes back online its once-poll entries (model info) are read again.
//  * The sender, the decode options and the hooks must outlive the node.
#pragma once

#include <functional>
#include <optional>

#include "gateway/node/frame_sender.h"
#include "gateway/node/lock_actuator.h"
#include "gateway/node/node_config.h"
#include "gateway/node/node_registry.h"
#include "gateway/node/own_broadcasts.h"
#include "gateway/node/poller.h"
#include "gateway/node/request_engine.h"
#include "gateway/node/shutdown.h"
#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::node {

struct NodeHooks {
  // Another node broadcast SHUTDOWN: save state now; READY is sent when this returns.
  std::function<void(motinova::Node initiator, Micros now)> on_peer_shutdown;
  // Our own shutdown procedure finished: switch the ACC line off (the hardware hook). Used when
  // start_shutdown() is given no callback of its own.
  std::function<void(const ShutdownOutcome&)> acc_off;
};

class IotNode {
 public:
  // Validates the config (throws std::invalid_argument naming the problem).
  IotNode(NodeConfig config, const motinova::DecodeOptions& options, FrameSender& sender,
          NodeHooks hooks = {});
  ~IotNode();
  IotNode(const IotNode&) = delete;
  IotNode& operator=(const IotNode&) = delete;

  void start(Micros now);
  void on_frame(const motinova::AppFrame& frame, const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // See the contract; Micros::max() when nothing is scheduled (not started).
  Micros next_event() const;
  // A lock job or the shutdown procedure is running: its outcome waits for the bus.
  bool latency_critical() const { return locks_.any_busy() || shutdown_.running(); }

  // Own fault word (iot_fault::kUplinkModule, kBle, kGps).
  void set_own_fault(uint32_t mask, bool active, Micros now);
  void set_own_faults(uint32_t word, Micros now);
  uint32_t own_faults() const { return broadcaster_.faults(); }

  // Vehicle-level LOCK 0x760/0x1104 and UNLOCK 0x760/0x1206 (one cancels the other's repeats).
  void vehicle_lock(Micros now);
  void vehicle_unlock(Micros now);

  // Physical lock k (0-based); see LockActuator.
  LockStart actuate_lock(int lock_index, LockTarget target, Micros now,
                         LockActuator::Callback on_done,
                         std::optional<Micros> timeout = std::nullopt);

  // §3.8.2. Waits for READY from the MC and the OBC if they are online. `acc_off` defaults to
  // hooks.acc_off. False if a shutdown is already running.
  bool start_shutdown(Micros now, ShutdownProcedure::AccOff acc_off = nullptr);
  // The same, but the ACC still goes off through hooks.acc_off and `observer` is told the
  // outcome afterwards (a remote power-off command confirms from the READY replies without
  // taking the hardware hook away).
  bool start_shutdown_observed(Micros now, ShutdownProcedure::AccOff observer);

  void set_poll_result_callback(Poller::ResultCallback cb) {
    poller_.set_result_callback(std::move(cb));
  }

  NodeRegistry& registry() { return registry_; }
  const NodeRegistry& registry() const { return registry_; }
  const Poller& poller() const { return poller_; }
  // The runtime's parked mode slows the poller down (Poller::set_parked_period).
  Poller& poller() { return poller_; }
  // Commands of other areas (MC settings, assist, CLEAR) submit here so that they queue behind
  // polls on the same ID instead of overlapping them.
  RequestEngine& requests() { return engine_; }
  const RequestEngine& requests() const { return engine_; }
  const OwnBroadcaster& broadcaster() const { return broadcaster_; }
  const LockActuator& locks() const { return locks_; }
  bool shutdown_running() const { return shutdown_.running(); }
  const NodeConfig& config() const { return config_; }

 private:
  // Re-reads a node's model info when it comes back (possibly a swapped battery).
  class Rearm final : public RegistryObserver {
   public:
    explicit Rearm(Poller& poller) : poller_(poller) {}
    void on_node_online(motinova::Node node, Micros now) override { poller_.rearm(node, now); }

   private:
    Poller& poller_;
  };

  NodeConfig config_;
  NodeHooks hooks_;
  // Declaration order is construction order: the engine outlives everything that submits to it.
  RequestEngine engine_;
  NodeRegistry registry_;
  Poller poller_;
  OwnBroadcaster broadcaster_;
  LockActuator locks_;
  ShutdownProcedure shutdown_;
  Rearm rearm_;
};

}  // namespace fleetgw::node
