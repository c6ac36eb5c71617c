// The one way the IoT-node logic puts a message on the bus.
//
// Contract:
//  * send() transmits one whole application frame: the implementation encodes it and queues all
//    of its CAN segments in one go, so two messages on one CAN ID are never interleaved.
//  * send() never blocks and never throws for a bus problem; it returns false when the frame
//    could not be queued (the caller counts a transmit failure and relies on its own retries).
//  * The node components call send() synchronously from on_frame()/tick()/API calls; they hold
//    a non-owning reference, so the sender must outlive them.
#pragma once

#include "motinova/frame.h"

namespace fleetgw::node {

class FrameSender {
 public:
  virtual ~FrameSender() = default;
  virtual bool send(const motinova::AppFrame& frame) = 0;
};

}  // namespace fleetgw::node
