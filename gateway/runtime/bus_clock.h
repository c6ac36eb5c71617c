// BusClock: the one place where the bus timeline and the engine's time meet. The core, the
// trackers and the command service run on the bus timeline (motinova::Micros): the simulator's
// accelerated virtual time, a replay's frame time, or the system clock on a real bus. The engine
// arms its timer on Env::steady_now(). A stage on the bus timeline asks this clock for its
// deadline in engine time (to_engine) and for the bus's "now", never converts by hand.
//
// Contract:
//  * on_frame(ts) is called for every frame delivered: once frames flow they are the clock of a
//    simulated or replayed bus (a machine too slow for the simulator's acceleration sees a
//    consistent, if slower, timeline).
//  * now(): the bus's present. System: Env::wall_now(). Simulated: the last frame's time, the
//    simulator's virtual clock before the first frame. Replay: the last frame's time.
//  * latest(): now(), or the simulator's virtual clock if it ran ahead of the frames delivered.
//  * to_engine(bus): the engine time at which the bus reaches `bus`; nullopt for a replay (its
//    clock only moves with its frames). The simulator's wait is divided by its speed and never
//    shorter than kMinSimWait.
#pragma once

#include <chrono>
#include <functional>
#include <optional>

#include "env/env.h"
#include "gateway/runtime/stage.h"
#include "motinova/can.h"

namespace fleetgw::runtime {

class BusClock {
 public:
  using Micros = motinova::Micros;
  static constexpr auto kMinSimWait = std::chrono::microseconds(200);

  // A real bus: the bus timeline is the system clock.
  static BusClock system(const Env& env) { return BusClock(env, Kind::kSystem, {}, 1.0); }
  // The simulator: virtual time running `speed` times faster than the engine's.
  static BusClock simulated(const Env& env, std::function<Micros()> virtual_now, double speed) {
    return BusClock(env, Kind::kSimulated, std::move(virtual_now), speed);
  }
  // A replay: the frames' own timestamps.
  static BusClock replay(const Env& env) { return BusClock(env, Kind::kReplay, {}, 1.0); }

  void on_frame(Micros ts) {
    if (first_frame_.count() < 0) first_frame_ = ts;
    last_frame_ = ts;
  }
  Micros now() const;
  Micros latest() const;
  std::optional<EngineTime> to_engine(Micros bus) const;

  bool replay() const { return kind_ == Kind::kReplay; }
  bool heard() const { return first_frame_.count() >= 0; }
  Micros first_frame() const { return first_frame_; }
  Micros last_frame() const { return last_frame_; }
  // Bus time covered by the frames delivered so far (0 before the first frame).
  double seconds_covered() const {
    return heard() ? static_cast<double>((last_frame_ - first_frame_).count()) / 1e6 : 0.0;
  }

 private:
  enum class Kind { kSystem, kSimulated, kReplay };
  BusClock(const Env& env, Kind kind, std::function<Micros()> virtual_now, double speed)
      : env_(&env), kind_(kind), virtual_now_(std::move(virtual_now)), speed_(speed) {}

  const Env* env_;
  Kind kind_;
  std::function<Micros()> virtual_now_;
  double speed_;
  Micros first_frame_{-1};
  Micros last_frame_{0};
};

}  // namespace fleetgw::runtime
