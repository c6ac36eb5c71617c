// FrameSender over a fleetgw::can::Transport: encodes the application frame with the configured
// CRC byte order (U1) and hands every CAN segment of it to the transport in one go.
//
// Contract:
//  * send() encodes, segments (motinova::segment, 8 bytes per CAN frame) and calls
//    Transport::send() once per segment, in order, without yielding in between. Because the
//    transport transmits in send order, one message's segments are never interleaved with another
//    message on the same ID.
//  * If the transport refuses a segment, the remaining segments of that message are not sent
//    (a receiver would drop the partial frame on its gap timeout anyway) and send() returns
//    false. Counters tell frames, segments and failures apart.
//  * CrcOrder::kAuto is a receive-side setting; for transmit it means big-endian (the spec's best
//    guess), as encode_frame() does.
//  * Holds a non-owning reference to the transport; not thread-safe (call it on the transport's
//    io_context thread, like everything in the node).
#pragma once

#include <cstdint>

#include "gateway/can/transport.h"
#include "gateway/node/frame_sender.h"
#include "motinova/frame.h"

namespace fleetgw::node {

struct TransportSenderStats {
  uint64_t frames_sent = 0;    // application frames fully queued
  uint64_t segments_sent = 0;  // CAN frames accepted by the transport
  uint64_t frames_failed = 0;  // application frames the transport refused (wholly or partly)
};

class TransportSender final : public FrameSender {
 public:
  TransportSender(can::Transport& transport, motinova::CrcOrder crc_order)
      : transport_(transport), crc_order_(crc_order) {}

  bool send(const motinova::AppFrame& frame) override;

  void set_crc_order(motinova::CrcOrder order) { crc_order_ = order; }
  motinova::CrcOrder crc_order() const { return crc_order_; }
  const TransportSenderStats& stats() const { return stats_; }

 private:
  can::Transport& transport_;
  motinova::CrcOrder crc_order_;
  TransportSenderStats stats_;
};

}  // namespace fleetgw::node
