// RateLimitedLog: logs a repeated identical error once per window, with a count, instead of on
// every attempt (a full disk retried at 100x replay speed must not write hundreds of lines/s).
//
// Contract:
// - report(message) logs `message` at once when it differs from the previous one or when the
//   window has passed since it was last logged; otherwise it only counts. The next line that
//   is logged for the same message says how many repetitions were suppressed, e.g.
//   "storage write failed: disk full (SQLITE_FULL) (repeated 312 times in the last 10 s)".
// - resolved(text) ends a stretch of errors: if anything was reported since the last
//   resolved(), one line at info level says so (with the count of suppressed repetitions).
// - Single-threaded; the clock is injected (default steady_clock) so tests need no sleeps.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

namespace spdlog {
class logger;
}

namespace fleetgw::storage {

class RateLimitedLog {
 public:
  using Clock = std::function<std::chrono::steady_clock::time_point()>;

  explicit RateLimitedLog(std::shared_ptr<spdlog::logger> logger,
                          std::chrono::steady_clock::duration window = std::chrono::seconds(10),
                          Clock clock = {});

  // Returns true when the line was written (false: counted only).
  bool report(std::string_view message);
  void resolved(std::string_view text);
  std::uint64_t suppressed() const { return suppressed_; }

 private:
  std::chrono::steady_clock::time_point now() const;

  std::shared_ptr<spdlog::logger> log_;
  std::chrono::steady_clock::duration window_;
  Clock clock_;
  std::string last_message_;
  std::chrono::steady_clock::time_point last_logged_{};
  std::uint64_t suppressed_ = 0;
  bool active_ = false;
};

}  // namespace fleetgw::storage
