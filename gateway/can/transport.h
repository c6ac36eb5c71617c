// One interface for every way fleetgw reaches a CAN bus: SocketCAN, candump replay, the UDP
// tunnel and the in-process simulator.
//
// Contract:
//  * A transport is bound to an asio::io_context at construction and delivers received frames
//    on that context's thread, in bus order, through the handler given to start().
//  * send() never blocks. Frames are transmitted in the order they were sent; a caller that
//    sends all segments of one application frame in one go therefore never interleaves two
//    messages on one CAN ID. send() returns false when the frame cannot be queued (interface
//    down, queue full); the caller counts that as a transmit failure.
//  * Health changes (link up/down, error-passive, bus-off, error frames) are reported through
//    the health handler. A transport that can recover (re-open) or must retry (a full driver
//    queue) exposes that timed work through timed_work() (timed_work.h) and keeps no timer of
//    its own: whoever runs it (the gateway's engine, runtime/stages.h TransportStage) polls it.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "gateway/can/timed_work.h"
#include "motinova/can.h"

namespace fleetgw::can {

// State of the CAN controller / interface as the bus sees it (ISO 11898 error states plus
// "interface down"); not to be confused with uplink::UplinkState, the MQTT connection.
enum class ControllerState : uint8_t { kUp, kErrorWarning, kErrorPassive, kBusOff, kDown };
std::string_view controller_state_name(ControllerState s);

struct BusHealth {
  ControllerState state = ControllerState::kDown;
  uint64_t rx_frames = 0;
  uint64_t tx_frames = 0;
  uint64_t tx_failures = 0;
  uint64_t error_frames = 0;  // CAN error frames seen (SocketCAN CAN_ERR_FLAG)
  uint64_t reopens = 0;       // successful re-opens after the interface went away
  std::string detail;         // last error text, e.g. "ENETDOWN on vcan0"
};

class Transport {
 public:
  using FrameHandler = std::function<void(const motinova::CanFrame&, motinova::Micros timestamp)>;
  using HealthHandler = std::function<void(const BusHealth&)>;

  virtual ~Transport() = default;
  virtual void start(FrameHandler on_frame, HealthHandler on_health) = 0;
  virtual bool send(const motinova::CanFrame& frame) = 0;
  virtual void stop() = 0;
  virtual const BusHealth& health() const = 0;
  virtual std::string_view name() const = 0;
  // The transport's timed work (re-open, transmit retry), or nullptr when it has none.
  virtual TimedWork* timed_work() { return nullptr; }
};

}  // namespace fleetgw::can
