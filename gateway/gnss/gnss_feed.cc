#include "gateway/gnss/gnss_feed.h"

#include <spdlog/spdlog.h>

namespace fleetgw::gnss {

GnssFeed::GnssFeed(asio::io_context& io, GnssFeedOptions options, Env& env,
                   std::function<void()> on_event)
    : io_(io),
      options_(std::move(options)),
      env_(env),
      on_event_(std::move(on_event)),
      client_(options_.host, options_.port),
      state_(options_.state) {}

GnssFeed::~GnssFeed() {
  stop();
}

void GnssFeed::stop() {
  stopped_ = true;
  if (socket_) {
    socket_->cancel();
    socket_->release();  // libgps owns the descriptor and closes it
    socket_.reset();
  }
  client_.close();
}

std::optional<std::string> GnssFeed::connect() {
  if (!needs_connect()) return std::nullopt;
  ++connect_attempts_;
  std::string error = client_.connect();
  if (!error.empty()) {
    state_.on_source_lost(wall_now());
    changed_ = true;
    return error + " (position unknown)";
  }
  spdlog::info("gnss: connected to gpsd at {}", client_.endpoint());
  state_.on_source_connected(wall_now());
  changed_ = true;
  socket_.emplace(io_, client_.fd());
  watch();
  return std::nullopt;
}

void GnssFeed::watch() {
  socket_->async_wait(asio::posix::stream_descriptor::wait_read,
                      [this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
                        if (ec || token.expired() || stopped_) return;
                        on_readable();
                      });
}

void GnssFeed::on_readable() {
  reports_.clear();
  const Micros now = wall_now();
  const auto status = client_.read_available(now, reports_);
  for (const GnssReport& r : reports_) {
    if (r.fix) {
      state_.on_fix(*r.fix);
    } else {
      state_.on_no_fix(now);
    }
    changed_ = true;
  }
  if (status == GpsdClient::ReadStatus::kClosed) {
    lost("gpsd closed the connection");
  } else {
    watch();
  }
  on_event_();
}

void GnssFeed::lost(const std::string& why) {
  if (socket_) {
    socket_->release();
    socket_.reset();
  }
  client_.close();
  state_.on_source_lost(wall_now());
  changed_ = true;
  loss_ = why + " (position unknown, reconnecting)";
}

std::optional<GnssFeed::Clock::time_point> GnssFeed::next_deadline() const {
  if (stopped_) return std::nullopt;
  const Micros now = wall_now();
  if (const auto stale_at = state_.next_change(now)) {
    return env_.steady_now() + std::chrono::duration_cast<Clock::duration>(*stale_at - now);
  }
  return std::nullopt;
}

void GnssFeed::on_timer() {
  if (stopped_) return;
  // A fix that went stale while nothing arrived: the owner re-reads the state.
  changed_ = true;
}

}  // namespace fleetgw::gnss
