#include "storage/rate_limited_log.h"

#include <spdlog/spdlog.h>

namespace fleetgw::storage {

RateLimitedLog::RateLimitedLog(std::shared_ptr<spdlog::logger> logger,
                               std::chrono::steady_clock::duration window, Clock clock)
    : log_(logger ? std::move(logger) : spdlog::default_logger()),
      window_(window),
      clock_(std::move(clock)) {}

std::chrono::steady_clock::time_point RateLimitedLog::now() const {
  return clock_ ? clock_() : std::chrono::steady_clock::now();
}

bool RateLimitedLog::report(std::string_view message) {
  const auto t = now();
  const bool same = active_ && message == last_message_;
  if (same && t - last_logged_ < window_) {
    ++suppressed_;
    return false;
  }
  if (same && suppressed_ > 0) {
    const auto secs = std::chrono::duration_cast<std::chrono::seconds>(t - last_logged_).count();
    log_->error("{} (repeated {} times in the last {} s)", message, suppressed_ + 1, secs);
  } else {
    if (active_ && suppressed_ > 0) {
      log_->error("{} (repeated {} more times)", last_message_, suppressed_);
    }
    log_->error("{}", message);
  }
  last_message_ = std::string(message);
  last_logged_ = t;
  suppressed_ = 0;
  active_ = true;
  return true;
}

void RateLimitedLog::resolved(std::string_view text) {
  if (!active_) return;
  if (suppressed_ > 0) {
    log_->info("{} (after '{}', repeated {} more times)", text, last_message_, suppressed_);
  } else {
    log_->info("{}", text);
  }
  active_ = false;
  suppressed_ = 0;
  last_message_.clear();
}

}  // namespace fleetgw::storage
