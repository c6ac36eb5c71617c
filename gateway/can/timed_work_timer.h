// TimedWorkTimer: runs a transport's TimedWork (timed_work.h) on one asio timer with the
// gateway's one retry schedule (env/backoff.h), for the programs that run a transport WITHOUT
// the gateway's engine: `fleetgw sim` serving a SocketCAN bus, the SocketCAN tests. The gateway
// (`fleetgw run`) never uses it: its engine polls the work (runtime/stages.h, TransportStage).
//
// Contract:
//  * start() takes over the work's wake hook (call it before the transport's start()) and
//    arms the timer for the work's next_deadline(), or a failed poll's retry time
//    (retry_spacing(): initial, doubling up to max; a success resets it).
//  * The timer is armed relative to the Env's steady clock; polls get env.steady_now().
//  * stop() or destruction cancels the timer; no handler runs afterwards. Single-threaded, on
//    the io_context's thread; `work` and `env` must outlive it.
#pragma once

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>
#include <memory>

#include "env/backoff.h"
#include "env/env.h"
#include "gateway/can/timed_work.h"

namespace fleetgw::can {

class TimedWorkTimer {
 public:
  TimedWorkTimer(asio::io_context& io, TimedWork& work, Env& env = Env::system());
  ~TimedWorkTimer();
  TimedWorkTimer(const TimedWorkTimer&) = delete;
  TimedWorkTimer& operator=(const TimedWorkTimer&) = delete;

  void start();
  void stop();
  const Backoff& backoff() const { return backoff_; }

 private:
  void arm();
  void fire();

  asio::steady_timer timer_;
  TimedWork& work_;
  Env& env_;
  Backoff backoff_;
  bool stopped_ = false;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

}  // namespace fleetgw::can
