// Env: the one injected environment of the gateway (LevelDB's `Env` is the model). Everything
// that reads a clock, starts a thread or touches a file outside SQLite does it through an Env
// given to it once at construction, so tests can drive all of it on one controllable clock.
//
// Contract:
//  * wall_now(): microseconds since the Unix epoch. What records, rate limits and the uplink
//    stamp with. May jump (NTP); never use it to measure an interval.
//  * steady_now(): a monotonic clock for intervals, deadlines and timeouts. The engine's one
//    timer is armed on it.
//  * start_thread(): the only way the gateway creates a thread; the function receives a stop
//    token, and the returned jthread requests stop and joins on destruction (RAII).
//  * The file operations cover what the gateway does to files outside SQLite (a corrupt store
//    moved aside, bundle and revocation files written atomically, free space checks); they
//    report failures as error codes, never by throwing.
//  * Env::system() is the real machine: stateless, thread-safe, lives for the program. It is
//    not global mutable state: it has no state.
//  * ManualEnv (tests): both clocks stand still until the test moves them; set/advance are
//    thread-safe, so a test thread may move time while the gateway's loop reads it.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <stop_token>
#include <string>
#include <string_view>
#include <system_error>
#include <thread>

namespace fleetgw {

class Env {
 public:
  using SteadyTime = std::chrono::steady_clock::time_point;
  using Micros = std::chrono::microseconds;

  virtual ~Env() = default;

  virtual Micros wall_now() const = 0;
  virtual SteadyTime steady_now() const = 0;

  // Starts `fn` on a new thread named `name` (at most 15 characters are kept, as Linux does).
  virtual std::jthread start_thread(std::string_view name, std::function<void(std::stop_token)> fn);

  // Atomically replaces `path` with `bytes` (write to a sibling temporary, fsync, rename).
  virtual std::error_code write_file_atomic(const std::filesystem::path& path,
                                            std::string_view bytes);
  virtual std::error_code rename_file(const std::filesystem::path& from,
                                      const std::filesystem::path& to);
  // Bytes available to an unprivileged writer on the file system holding `path`.
  virtual std::error_code free_space(const std::filesystem::path& path, std::uint64_t& bytes);

  // The real machine.
  static Env& system();
};

// Both clocks under the test's control (see the contract). Starts at `wall` on the wall clock
// and at an arbitrary fixed point on the steady clock.
class ManualEnv final : public Env {
 public:
  explicit ManualEnv(Micros wall = Micros(1'700'000'000'000'000));

  Micros wall_now() const override { return Micros(wall_us_.load()); }
  SteadyTime steady_now() const override {
    return SteadyTime(std::chrono::nanoseconds(steady_ns_.load()));
  }
  // Moves both clocks forward by `d` (negative durations are ignored: time never runs back).
  void advance(std::chrono::nanoseconds d);
  // Sets the wall clock alone (an NTP step); the steady clock does not move.
  void set_wall(Micros wall) { wall_us_.store(wall.count()); }

 private:
  std::atomic<std::int64_t> wall_us_;
  std::atomic<std::int64_t> steady_ns_{1'000'000'000};
};

}  // namespace fleetgw
