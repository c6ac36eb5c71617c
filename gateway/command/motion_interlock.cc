#include "gateway/command/motion_interlock.h"

#include <fmt/format.h>

#include "gateway/node/messages.h"
#include "motinova/catalogue.h"

namespace fleetgw::command {

std::map<std::string, InterlockRule> default_interlocks() {
  return {
      {"frame", {.block_lock_while_moving = true}},
      {"wheel", {.block_lock_while_moving = true}},
      {"rear_wheel", {.block_lock_while_moving = true}},
      // A steering lock engaging at speed is a crash.
      {"steering", {.block_lock_while_moving = true}},
      {"battery", {.block_unlock_while_moving = true}},
  };
}

MotionInterlock::MotionInterlock(InterlockSettings settings) : settings_(std::move(settings)) {}

void MotionInterlock::observe_mc_status(const motinova::DecodedMessage& msg, Micros at) {
  const auto speed = msg.number("speed_kmh");
  const auto rpm = msg.number("motor_rpm");
  if (!speed && !rpm) return;
  if (!last_reading_ || at >= *last_reading_) {
    last_reading_ = at;
    last_speed_kmh_ = speed.value_or(0);
  }
  if (rpm && *rpm > 0 && (!last_rpm_positive_ || at > *last_rpm_positive_)) {
    last_rpm_positive_ = at;
  }
}

std::optional<bool> MotionInterlock::moving(const node::NodeRegistry& registry, Micros now) {
  // The registry keeps the MC's latest mc_status even when decoded messages are not forwarded.
  const auto& mc = registry.node(motinova::Node::kMc);
  if (const auto* snap = mc.find(node::ids::kMcBroadcast, 0x10)) {
    motinova::DecodedMessage decoded;
    motinova::decode(snap->frame, motinova::Catalogue::standard(), settings_.decode_options,
                     decoded);
    if (decoded.status == motinova::DecodeStatus::kOk) observe_mc_status(decoded, snap->received);
  }
  if (last_rpm_positive_ && now - *last_rpm_positive_ <= settings_.motor_window) return true;
  if (!last_reading_ || now - *last_reading_ > settings_.motion_max_age) return std::nullopt;
  return last_speed_kmh_ > settings_.speed_kmh;
}

std::optional<Rejection> MotionInterlock::check(std::string_view kind, node::LockTarget target,
                                                const node::NodeRegistry& registry, Micros now) {
  const auto it = settings_.rules.find(std::string(kind));
  if (it == settings_.rules.end()) return std::nullopt;
  const bool locking = target == node::LockTarget::kLocked;
  const bool guarded =
      locking ? it->second.block_lock_while_moving : it->second.block_unlock_while_moving;
  if (!guarded) return std::nullopt;
  const auto m = moving(registry, now);
  if (m && !*m) return std::nullopt;
  const std::string what =
      std::string(locking ? "lock" : "unlock") + " the " + std::string(kind) + " lock";
  if (!m) {
    if (!settings_.motion_unknown_blocks) return std::nullopt;
    return Rejection{RejectReason::kInterlockMotionUnknown,
                     "will not " + what + ": no recent mc_status, motion unknown",
                     {},
                     true};
  }
  return Rejection{RejectReason::kInterlockMoving,
                   "will not " + what + " while the bike moves (speed " +
                       fmt::format("{:.1f}", last_speed_kmh_) + " km/h or motor turning within " +
                       std::to_string(settings_.motor_window.count() / 1'000'000) + " s)",
                   {},
                   true};
}

}  // namespace fleetgw::command
