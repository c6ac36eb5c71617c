// The production transport: a raw SocketCAN socket (PF_CAN, SOCK_RAW, CAN_RAW) on a named
// interface (can0 on the bike, vcan0 in tests).
//
// Contract:
//  * Construction opens and binds the socket and throws SocketCanError with a clear message when
//    that is impossible for a reason that will not fix itself: no SocketCAN in the kernel
//    (EAFNOSUPPORT: "this kernel has no SocketCAN support"), CAN_RAW missing, or no interface of
//    that name. An interface that exists but is down is not an error: the transport starts in
//    kDown and comes up by itself.
//  * The kernel acceptance filter passes only standard data frames 0x700-0x7FF (can_id 0x700,
//    mask 0x700 | CAN_EFF_FLAG | CAN_RTR_FLAG), so the rest of the bus never reaches user space.
//    Error frames (kSubscribedErrorClasses) are enabled and turned into health: kErrorWarning,
//    kErrorPassive, kBusOff, and kUp again after a restart or recovery.
//  * Frame timestamps are the kernel's receive timestamps (SO_TIMESTAMPNS), microseconds since
//    the Unix epoch, not the time user space got around to reading. They never run backwards by
//    less than a second (see TimestampGuard: small regressions are clamped, bigger ones are wall
//    clock steps and pass through); both are counted in stats().
//  * send() never blocks: frames go into a bounded TxQueue (tx_queue_limit) drained in order; a
//    full queue or a down link makes send() return false and counts a tx failure. ENOBUFS
//    (driver queue full, common at 250 kbit/s) is retried tx_retry_interval later; frames are
//    never reordered.
//  * When the interface goes down (ENETDOWN/ENODEV or any other read/write error) the socket is
//    closed, the state is kDown, queued frames are dropped (counted as tx failures) and it is
//    re-opened until the interface is up again; each success counts in health().reopens.
//  * No timer of its own: the ENOBUFS retry and the re-opening are its TimedWork
//    (timed_work.h), done when its owner polls it -- the gateway's engine, whose one back-off
//    spaces the re-open attempts (reopen_interval, doubling up to reopen_max: TransportStage).
//    Time is read from the Env given at construction (env/env.h).
//  * Single-threaded: all member functions must be called on the io_context's thread; handlers
//    run there too. Destruction or stop() cancels everything; no handler runs afterwards.
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include <asio/io_context.hpp>
#include <asio/posix/stream_descriptor.hpp>
#include "env/env.h"
#include "gateway/can/timed_work.h"
#include "gateway/can/timestamp_guard.h"
#include "gateway/can/transport.h"
#include "gateway/can/tx_queue.h"

namespace fleetgw::can {

class SocketCanError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SocketCanOptions {
  std::string interface = "can0";
  std::chrono::milliseconds reopen_interval{500};  // the first re-open's wait (back-off start)
  std::chrono::milliseconds reopen_max{5000};      // the longest wait between re-open attempts
  std::chrono::milliseconds tx_retry_interval{2};
  std::size_t tx_queue_limit = 256;
  std::size_t rx_batch = 64;  // frames read per readiness event before yielding to the loop
};

// Counters beyond BusHealth, for diagnostics and tests.
struct SocketCanStats {
  uint64_t rx_unexpected = 0;          // frames the filter should have stopped (EFF/RTR/odd size)
  uint64_t rx_no_timestamp = 0;        // frames without a kernel timestamp (fell back to the clock)
  uint64_t rx_timestamps_clamped = 0;  // earlier than the previous frame's: clamped to it
  uint64_t rx_clock_steps = 0;         // wall clock set back by more than a second
  uint64_t tx_enobufs_retries = 0;
  uint64_t reopen_attempts = 0;
};

class SocketCanTransport final : public Transport, private TimedWork {
 public:
  // `env` (the steady clock of the transmit retry) must outlive the transport.
  SocketCanTransport(asio::io_context& io, SocketCanOptions options, Env& env = Env::system());
  ~SocketCanTransport() override;

  SocketCanTransport(const SocketCanTransport&) = delete;
  SocketCanTransport& operator=(const SocketCanTransport&) = delete;

  void start(FrameHandler on_frame, HealthHandler on_health) override;
  bool send(const motinova::CanFrame& frame) override;
  void stop() override;
  const BusHealth& health() const override { return health_; }
  std::string_view name() const override { return name_; }
  TimedWork* timed_work() override { return this; }
  const SocketCanOptions& options() const { return options_; }

  const SocketCanStats& stats() const { return stats_; }
  std::size_t tx_queue_size() const { return tx_.size(); }

 private:
  // Opens and binds a socket; returns false with `why` set on a transient failure (interface
  // down or missing), throws SocketCanError when `fatal_errors` and the cause is permanent.
  bool open(bool fatal_errors, std::string& why);
  void close_socket();
  void wait_readable();
  void on_readable();
  void handle_error_frame(uint32_t can_id, const uint8_t* data, uint8_t len);
  void flush_tx();
  void wait_writable();
  void link_lost(int err, std::string_view during);
  // TimedWork: the transmit retry, then a re-open attempt while the socket is closed.
  std::optional<TimedWork::Time> next_deadline() const override;
  std::optional<std::string> poll(TimedWork::Time now) override;
  RetrySpacing retry_spacing() const override {
    return {options_.reopen_interval, options_.reopen_max};
  }
  std::optional<std::string> reopen();
  void set_state(ControllerState s, std::string detail, bool force = false);

  asio::io_context& io_;
  SocketCanOptions options_;
  Env& env_;
  std::string name_;
  asio::posix::stream_descriptor sock_;
  TxQueue tx_;  // held while a write-readiness wait or ENOBUFS retry is pending
  std::optional<TimedWork::Time> tx_retry_at_;  // ENOBUFS: when to write again
  std::optional<std::string> loss_;             // the link went down: the next poll() reports it

  FrameHandler on_frame_;
  HealthHandler on_health_;
  BusHealth health_;
  SocketCanStats stats_;
  TimestampGuard ts_guard_;
  bool started_ = false;
  bool stopped_ = false;
  // Handlers hold a weak reference; once stop()/destruction resets it they return untouched.
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

}  // namespace fleetgw::can
