// Service-manager notifications (the sd_notify protocol) and the event-loop watchdog.
//
// Contract:
//  * Notifier sends sd_notify state strings ("READY=1", "WATCHDOG=1", "STATUS=...",
//    "STOPPING=1") as one datagram to the AF_UNIX socket named by NOTIFY_SOCKET (a path, or
//    "@name" for the abstract namespace). Without NOTIFY_SOCKET it is disabled and every call is
//    a cheap no-op returning false, so the service behaves the same when started by hand.
//    Sending never throws and never blocks the event loop (non-blocking datagram).
//  * Watchdog turns "the event loop is alive" into WATCHDOG=1 pings: the loop calls
//    loop_alive(now) from its own timer; a ping goes out when half of systemd's WatchdogSec has
//    passed since the last one. Because the call comes from the loop itself, a stalled or
//    dead-locked loop stops pinging and systemd restarts the service (Restart=on-failure).
//  * LoopWatchdog is that timer: it re-arms itself on an asio::io_context every quarter of the
//    timeout. It must be destroyed before its io_context; stop() cancels it. It stays a timer
//    of its own, outside the engine, on purpose: it proves that the loop turns, whatever the
//    engine's stages do (and it is no part of the data's road).
//  * Time is passed in (steady clock); LoopWatchdog reads it from the Env it is given
//    (env/env.h), nothing here reads a clock of its own.
#pragma once

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>
#include <chrono>
#include <optional>
#include <string>
#include <string_view>

#include "env/env.h"

namespace fleetgw::status {

class Notifier {
 public:
  // Reads NOTIFY_SOCKET. An unusable value (e.g. a relative path) leaves the notifier disabled.
  static Notifier from_environment();

  // `socket` as in NOTIFY_SOCKET; empty = disabled.
  explicit Notifier(std::string socket = {});

  bool enabled() const { return !socket_.empty(); }
  const std::string& socket() const { return socket_; }

  // "READY=1" (plus "STATUS=<text>" when given): the bus and the store are open.
  bool ready(std::string_view status_text = {});
  bool watchdog();                     // "WATCHDOG=1"
  bool status(std::string_view text);  // "STATUS=<text>", shown by systemctl status
  bool stopping();                     // "STOPPING=1": clean shutdown has begun
  // Sends a raw newline-separated state string. True when the datagram was accepted.
  bool notify(std::string_view state);

 private:
  std::string socket_;
};

// systemd's watchdog timeout for this process: WATCHDOG_USEC when set and positive, and
// WATCHDOG_PID (if set) names this process. nullopt = no watchdog requested.
std::optional<std::chrono::microseconds> watchdog_timeout_from_environment();
// The same decision from explicit values (testable): usec/pid may be null.
std::optional<std::chrono::microseconds> parse_watchdog_env(const char* usec, const char* pid,
                                                            long self_pid);

class Watchdog {
 public:
  using Clock = std::chrono::steady_clock;

  // `timeout` is the service's WatchdogSec; pings go out every timeout / 2.
  Watchdog(Notifier& notifier, std::chrono::microseconds timeout);

  // Called by the event loop. Pings when no ping was sent yet or half the timeout has passed
  // since the last one; returns true when it pinged.
  bool loop_alive(Clock::time_point now);

  Clock::duration ping_period() const { return ping_period_; }
  // How often the loop should call loop_alive(): often enough that timer jitter never lets the
  // gap between two pings approach the timeout.
  Clock::duration check_period() const { return ping_period_ / 2; }
  uint64_t pings() const { return pings_; }

 private:
  Notifier& notifier_;
  Clock::duration ping_period_;
  std::optional<Clock::time_point> last_ping_;
  uint64_t pings_ = 0;
};

// The asio timer that feeds a Watchdog from the event loop it guards.
class LoopWatchdog {
 public:
  // `env` must outlive the watchdog.
  LoopWatchdog(asio::io_context& io, Notifier& notifier, std::chrono::microseconds timeout,
               Env& env = Env::system());
  ~LoopWatchdog();
  LoopWatchdog(const LoopWatchdog&) = delete;
  LoopWatchdog& operator=(const LoopWatchdog&) = delete;

  void start();  // first ping immediately from the loop, then every check_period()
  void stop();
  const Watchdog& watchdog() const { return watchdog_; }

 private:
  void arm();
  Watchdog watchdog_;
  asio::steady_timer timer_;
  Env& env_;
  bool running_ = false;
};

}  // namespace fleetgw::status
