// RateLimitedLog: logs a repeated identical error once per window, with a count, instead of on
// every attempt (a full disk retried at 100x replay speed must not write hundreds of lines/s).
//
// Contract:
// - report(message) logs `message` at once when it was not logged within the last window;
//   otherwise it only counts. Each distinct message has its own window and count (up to
//   kMaxTracked of them, the least recently logged forgotten first), so errors that alternate
//   ("write failed", "ack failed", ...) are limited as well as a single repeated one. The next
//   line logged for a message says how many repetitions were suppressed, e.g.
//   "storage write failed: disk full (SQLITE_FULL) (repeated 312 times in the last 10 s)".
// - resolved(text) ends a stretch of errors: if anything was reported since the last
//   resolved(), one line at info level says so (with the counts of suppressed repetitions).
//   The windows are kept: a message that comes back within its window is counted, not logged.
// - Single-threaded; windows are measured on the Env's steady clock (env/env.h), so tests drive
//   them with a ManualEnv and need no sleeps.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "env/env.h"

namespace spdlog {
class logger;
}

namespace fleetgw::storage {

class RateLimitedLog {
 public:
  static constexpr std::size_t kMaxTracked = 16;

  explicit RateLimitedLog(std::shared_ptr<spdlog::logger> logger,
                          std::chrono::steady_clock::duration window = std::chrono::seconds(10),
                          Env& env = Env::system());

  // Returns true when the line was written (false: counted only).
  bool report(std::string_view message);
  void resolved(std::string_view text);
  // Repetitions counted but not yet reported in a line, over all messages.
  std::uint64_t suppressed() const;

 private:
  struct Tracked {
    std::string message;
    std::chrono::steady_clock::time_point last_logged;
    std::uint64_t suppressed = 0;
  };
  std::shared_ptr<spdlog::logger> log_;
  std::chrono::steady_clock::duration window_;
  Env* env_;
  std::vector<Tracked> tracked_;  // at most kMaxTracked; small, so a linear search
  bool active_ = false;
};

}  // namespace fleetgw::storage
