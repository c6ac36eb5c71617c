// A transport whose bus keeps its own timeline, paced against the wall clock: the simulated
// bike (gateway/sim/sim_transport.h, SimTransport). The runtime drives a simulated bus only
// through this interface, so the service libraries never link the simulator; whoever runs it
// (the fleetgw binary, tests) opens one and hands it over (runtime/service.h, open_sim).
//
// Contract (on top of Transport's):
//  * virtual_now() is the bus's clock: Micros on its timeline, the timestamps its frames carry.
//    It moves with the wall clock times the transport's acceleration.
//  * Frames may be delivered in batches: set_batch_window(w) lets the transport wake at most
//    once per `w` of real time, each frame still stamped with its own bus time;
//    set_low_latency(true) suspends batching (something waits for the bus's answer); flush()
//    delivers at once everything due by virtual_now(). Window 0: no batching.
#pragma once

#include <chrono>

#include "gateway/can/transport.h"

namespace fleetgw::can {

class PacedTransport : public Transport {
 public:
  virtual motinova::Micros virtual_now() const = 0;
  virtual void set_batch_window(std::chrono::steady_clock::duration window) = 0;
  virtual void set_low_latency(bool on) = 0;
  virtual void flush() = 0;
};

}  // namespace fleetgw::can
