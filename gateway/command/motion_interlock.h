// MotionInterlock: decides whether a lock action is refused because the bike moves, or because
// nobody can tell whether it moves.
//
// Contract:
//  * Motion evidence is the MC's mc_status (speed_kmh, motor_rpm): fed by observe_mc_status()
//    (every decoded message) and, at each check, from the node registry's latest mc_status
//    snapshot (so the interlock works even when decoded messages are not forwarded).
//  * moving(now): true when the motor turned within `motor_window` or the latest speed is above
//    `speed_kmh`; false when a reading no older than `motion_max_age` shows neither; nullopt
//    (unknown) when there is no reading or the latest is older than `motion_max_age` -- a silent
//    MC does not mean a still wheel.
//  * check(kind, target, now) applies the rule of that lock kind (InterlockRule): a guarded
//    action is refused with interlock_moving when moving, and with interlock_motion_unknown when
//    motion is unknown and `motion_unknown_blocks` is set. Unguarded kinds/actions pass.
//  * Pure apart from reading the registry: no bus, no clock, no I/O.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/command/verifier.h"
#include "gateway/node/node_registry.h"
#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::command {

// When an action on a lock kind is refused while the bike moves.
struct InterlockRule {
  bool block_lock_while_moving = false;    // e.g. frame: a bolt must never hit a turning wheel
  bool block_unlock_while_moving = false;  // e.g. battery: never released while riding
};

// frame/wheel/rear_wheel/steering: lock blocked; battery: unlock blocked.
std::map<std::string, InterlockRule> default_interlocks();

struct InterlockSettings {
  std::map<std::string, InterlockRule> rules = default_interlocks();
  double speed_kmh = 1.0;
  Micros motor_window = 5s;
  Micros motion_max_age = 1s;
  bool motion_unknown_blocks = true;
  motinova::DecodeOptions decode_options{};  // to decode the registry's mc_status snapshot
};

class MotionInterlock {
 public:
  explicit MotionInterlock(InterlockSettings settings);

  void observe_mc_status(const motinova::DecodedMessage& msg, Micros at);
  std::optional<bool> moving(const node::NodeRegistry& registry, Micros now);
  // The rejection (reason, detail; authenticated, no command id) refusing `target` on a lock
  // of `kind` right now, if any.
  std::optional<Rejection> check(std::string_view kind, node::LockTarget target,
                                 const node::NodeRegistry& registry, Micros now);

 private:
  InterlockSettings settings_;
  std::optional<Micros> last_rpm_positive_;
  std::optional<Micros> last_reading_;
  double last_speed_kmh_ = 0;
};

}  // namespace fleetgw::command
