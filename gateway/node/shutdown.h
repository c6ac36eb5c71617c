// The IoT-initiated power-down of §3.8.2: broadcast SHUTDOWN (0x760/0x1008), optionally order
// the OBC off (0x763/0x7008), wait for READY from the MC (0x710/0x1305) and the OBC
// (0x730/0x1405) or ~1 s, then switch the ACC line off through the `acc_off` hook.
//
// Contract:
//  * start() names the nodes to wait for (the facade passes those currently online: a node that
//    is not on the bus cannot answer, and waiting for it would only delay the power-off). With
//    nothing to wait for, the procedure completes within the same call.
//  * SHUTDOWN goes out through the OwnBroadcaster as an event (sent at once, repeated per
//    BroadcastPolicy); the repeats stop as soon as every awaited READY arrived.
//  * Completion calls the hook exactly once with which READYs arrived and whether the wait
//    timed out. READYs heard before start() do not count.
//  * One procedure at a time: start() while one runs returns false and changes nothing.
#pragma once

#include <functional>

#include "gateway/node/node_config.h"
#include "gateway/node/own_broadcasts.h"
#include "gateway/node/request_engine.h"

namespace fleetgw::node {

struct ShutdownOutcome {
  bool awaited_mc = false;
  bool awaited_obc = false;
  bool mc_ready = false;
  bool obc_ready = false;
  bool timed_out = false;  // at least one awaited READY did not arrive within ready_timeout
  Micros elapsed{0};
};

class ShutdownProcedure {
 public:
  using AccOff = std::function<void(const ShutdownOutcome&)>;

  ShutdownProcedure(ShutdownPolicy policy, OwnBroadcaster& broadcaster, RequestEngine& engine);

  bool start(Micros now, bool await_mc, bool await_obc, AccOff acc_off);
  void on_frame(const motinova::AppFrame& frame, Micros now);
  void tick(Micros now);
  // The READY wait's timeout while running (Micros::max(): not running).
  Micros next_event() const { return running_ ? started_ + policy_.ready_timeout : Micros::max(); }
  bool running() const { return running_; }

 private:
  void finish(bool timed_out, Micros now);

  ShutdownPolicy policy_;
  OwnBroadcaster& broadcaster_;
  RequestEngine& engine_;
  bool running_ = false;
  Micros started_{0};
  ShutdownOutcome outcome_;
  AccOff acc_off_;
};

// True for the READY broadcasts of §3.8.2 step 2.
bool is_mc_ready(const motinova::AppFrame& frame);
bool is_obc_ready(const motinova::AppFrame& frame);
// True for a SHUTDOWN broadcast by another node: OBC 0x730/0x1008 or BMS 0x720/0x1308.
bool is_peer_shutdown(const motinova::AppFrame& frame);

}  // namespace fleetgw::node
