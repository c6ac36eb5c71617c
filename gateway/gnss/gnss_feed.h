// GnssFeed: gpsd on the gateway's event loop -- connects when asked, watches the socket, and
// keeps the GnssState. It never blocks the loop on reads and never calls into other stages: the
// owner (the runtime's GnssStage) asks changed() after an event and applies the state.
//
// Contract:
//  * The feed does not time its reconnects: the ENGINE does, with its one back-off
//    (gateway/runtime/backoff.h). While needs_connect(), the owner calls connect() when its
//    retry is due; a failure is returned as text (the owner reports it as its stage's error,
//    which the engine logs once per distinct reason and retries after reconnect_min, doubling
//    up to reconnect_max: GnssFeedOptions are those Backoff options); a success is logged.
//  * A connection lost while reading is reported once by take_loss() (the owner reports it as
//    its error too, so the first reconnect waits the back-off instead of hammering a gpsd that
//    just went away).
//  * Readability of the gpsd socket posts `on_event` (the owner's "something happened" hook,
//    e.g. request a settle); changed() is then true until take_changed() is called.
//  * next_deadline() is the steady time at which the current fix goes stale; the owner calls
//    on_timer() when its timer reaches it.
//  * Time comes from the Env it is given (env/env.h), never from a clock of its own: positions
//    are judged on env.wall_now() (when they were received, whatever the bus's possibly virtual
//    timeline); next_deadline() is on env.steady_now().
#pragma once

#include <asio/io_context.hpp>
#include <asio/posix/stream_descriptor.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "env/env.h"
#include "gateway/gnss/gnss_state.h"
#include "gateway/gnss/gpsd_client.h"

namespace fleetgw::gnss {

struct GnssFeedOptions {
  std::string host = "localhost";
  std::string port = "2947";
  GnssOptions state;
  std::chrono::milliseconds reconnect_min{1000};
  std::chrono::milliseconds reconnect_max{30000};
};

class GnssFeed {
 public:
  using Clock = std::chrono::steady_clock;
  // `env` must outlive the feed.
  GnssFeed(asio::io_context& io, GnssFeedOptions options, Env& env,
           std::function<void()> on_event);
  ~GnssFeed();
  GnssFeed(const GnssFeed&) = delete;
  GnssFeed& operator=(const GnssFeed&) = delete;

  void stop();

  // Not connected and not stopped: the owner calls connect() when its back-off allows.
  bool needs_connect() const { return !stopped_ && !socket_; }
  // One connection attempt; the reason on failure (the state is then "unknown").
  std::optional<std::string> connect();
  // Why the connection was lost since the last call, once.
  std::optional<std::string> take_loss() { return std::exchange(loss_, std::nullopt); }
  std::uint64_t connect_attempts() const { return connect_attempts_; }

  std::optional<Clock::time_point> next_deadline() const;
  void on_timer();

  bool changed() const { return changed_; }
  void take_changed() { changed_ = false; }
  const GnssState& state() const { return state_; }
  const GnssFeedOptions& options() const { return options_; }
  Micros wall_now() const { return env_.wall_now(); }
  bool connected() const { return client_.connected(); }
  std::string endpoint() const { return client_.endpoint(); }

 private:
  void watch();
  void on_readable();
  void lost(const std::string& why);

  asio::io_context& io_;
  GnssFeedOptions options_;
  Env& env_;
  std::function<void()> on_event_;
  GpsdClient client_;
  GnssState state_;
  std::optional<asio::posix::stream_descriptor> socket_;
  std::optional<std::string> loss_;
  std::uint64_t connect_attempts_ = 0;
  bool changed_ = true;  // the initial "unknown" is news too (sets the fault bit)
  bool stopped_ = false;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
  std::vector<GnssReport> reports_;
};

}  // namespace fleetgw::gnss
