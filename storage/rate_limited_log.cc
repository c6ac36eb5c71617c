#include "storage/rate_limited_log.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace fleetgw::storage {

RateLimitedLog::RateLimitedLog(std::shared_ptr<spdlog::logger> logger,
                               std::chrono::steady_clock::duration window, Env& env)
    : log_(logger ? std::move(logger) : spdlog::default_logger()), window_(window), env_(&env) {}

std::uint64_t RateLimitedLog::suppressed() const {
  std::uint64_t n = 0;
  for (const auto& t : tracked_) n += t.suppressed;
  return n;
}

bool RateLimitedLog::report(std::string_view message) {
  const auto t = env_->steady_now();
  active_ = true;
  auto it = std::find_if(tracked_.begin(), tracked_.end(),
                         [&](const Tracked& x) { return x.message == message; });
  if (it != tracked_.end() && t - it->last_logged < window_) {
    ++it->suppressed;
    return false;
  }
  if (it != tracked_.end()) {
    if (it->suppressed > 0) {
      const auto secs =
          std::chrono::duration_cast<std::chrono::seconds>(t - it->last_logged).count();
      log_->error("{} (repeated {} times in the last {} s)", message, it->suppressed + 1, secs);
    } else {
      log_->error("{}", message);
    }
    it->last_logged = t;
    it->suppressed = 0;
    return true;
  }
  if (tracked_.size() >= kMaxTracked) {
    // Forget the least recently logged message, saying what was still uncounted.
    auto oldest = std::min_element(
        tracked_.begin(), tracked_.end(),
        [](const Tracked& a, const Tracked& b) { return a.last_logged < b.last_logged; });
    if (oldest->suppressed > 0) {
      log_->error("{} (repeated {} more times)", oldest->message, oldest->suppressed);
    }
    tracked_.erase(oldest);
  }
  log_->error("{}", message);
  tracked_.push_back({std::string(message), t, 0});
  return true;
}

void RateLimitedLog::resolved(std::string_view text) {
  if (!active_) return;
  std::string counts;
  for (const auto& t : tracked_) {
    if (t.suppressed == 0) continue;
    counts += counts.empty() ? " (after " : "; ";
    counts += "'" + t.message + "', repeated " + std::to_string(t.suppressed) + " more times";
  }
  if (!counts.empty()) counts += ")";
  log_->info("{}{}", text, counts);
  active_ = false;
  // The windows run on: a disk that flips between full and working at every retry must not
  // log its failure again at every flip.
  for (auto& t : tracked_) t.suppressed = 0;
}

}  // namespace fleetgw::storage
