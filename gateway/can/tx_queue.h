// The transmit queue shared by the transports that write to a socket (SocketCAN, UDP tunnel).
//
// Contract:
//  * Bounded FIFO of CAN frames: push() never blocks and returns false when `limit` frames are
//    already queued (the transport counts that as a transmit failure). Frames leave in push()
//    order; the transport removes them from the front with pop() once they are written.
//  * Writing happens from the io_context loop, never inside push(): the first push() of a loop
//    turn posts one call of the drain function, so every frame pushed in that turn is written in
//    one go and the caller gets no re-entrant callbacks.
//  * While the transport waits for its socket (writable again, an ENOBUFS retry, a datagram in
//    flight) it holds the queue (hold()/release()); push() then only queues and the transport
//    drains again itself when the wait ends.
//  * Nothing runs after stop() or destruction (a posted drain finds the queue gone and returns).
//  * Single-threaded: use on the io_context's thread only.
#pragma once

#include <cstddef>
#include <deque>
#include <functional>
#include <memory>

#include <asio/io_context.hpp>

#include "motinova/can.h"

namespace fleetgw::can {

// Only classic standard frames (11-bit ID, at most 8 data bytes) are ever put on the bus.
bool is_sendable(const motinova::CanFrame& frame);

class TxQueue {
 public:
  // `limit` must be > 0 (std::invalid_argument). `drain` writes as much of the queue as the
  // socket takes; it is called from the loop only.
  TxQueue(asio::io_context& io, std::size_t limit, std::function<void()> drain);

  TxQueue(const TxQueue&) = delete;
  TxQueue& operator=(const TxQueue&) = delete;

  // Until start() frames only queue (the transport drains once itself when it starts).
  void start() { started_ = true; }
  void stop();

  bool push(const motinova::CanFrame& frame);

  void hold() { held_ = true; }
  void release() { held_ = false; }
  bool held() const { return held_; }

  bool empty() const { return frames_.empty(); }
  std::size_t size() const { return frames_.size(); }
  const motinova::CanFrame& front() const { return frames_.front(); }
  const motinova::CanFrame& operator[](std::size_t i) const { return frames_[i]; }
  void pop(std::size_t count = 1);
  // Drops every queued frame (link lost); returns how many were dropped.
  std::size_t drop_all();

 private:
  asio::io_context& io_;
  std::size_t limit_;
  std::function<void()> drain_;
  std::deque<motinova::CanFrame> frames_;
  bool started_ = false;
  bool held_ = false;  // a drain is posted or the transport waits for its socket
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

}  // namespace fleetgw::can
