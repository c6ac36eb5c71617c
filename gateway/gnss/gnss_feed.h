// GnssFeed: gpsd on the gateway's event loop -- connects, watches the socket, reconnects with
// backoff, and keeps the GnssState. It never blocks the loop on reads and never calls into
// other stages: the owner (the Pipeline) asks changed() after an event and applies the state.
//
// Contract:
//  * start() makes the first connection attempt; a failure is logged once per distinct reason
//    and retried after reconnect_min, doubling up to reconnect_max; the first success after a
//    failure is logged.
//  * Readability of the gpsd socket posts `on_event` (the owner's "something happened" hook,
//    e.g. request a settle); changed() is then true until take_changed() is called.
//  * next_deadline() is the wall time of the next reconnect attempt or of the current fix going
//    stale; the owner calls on_timer() when its timer reaches it.
//  * Time comes from the Env it is given (env/env.h), never from a clock of its own: positions
//    are judged on env.wall_now() (when they were received, whatever the bus's possibly virtual
//    timeline); reconnect back-off and next_deadline() are on env.steady_now().
#pragma once

#include <asio/io_context.hpp>
#include <asio/posix/stream_descriptor.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>

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

  void start();
  void stop();

  std::optional<Clock::time_point> next_deadline() const;
  void on_timer();

  bool changed() const { return changed_; }
  void take_changed() { changed_ = false; }
  const GnssState& state() const { return state_; }
  Micros wall_now() const { return env_.wall_now(); }
  bool connected() const { return client_.connected(); }
  std::string endpoint() const { return client_.endpoint(); }

 private:
  void try_connect();
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
  std::optional<Clock::time_point> reconnect_at_;
  std::chrono::milliseconds backoff_;
  std::string last_error_;
  bool changed_ = true;  // the initial "unknown" is news too (sets the fault bit)
  bool stopped_ = false;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
  std::vector<GnssReport> reports_;
};

}  // namespace fleetgw::gnss
