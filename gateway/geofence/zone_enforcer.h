// ZoneEnforcer: turns the engine's demands into the MC writes that follow them -- the speed
// limit and the assist level of issue 13's MC actions -- one at a time, and restores what was
// there before. Pure logic: no clock, no bus; the runtime asks next(), starts the write through
// the MC command path (command::McActionRunner) and reports the outcome with on_result().
//
// Contract:
//  * next(demands, mc, now) returns the write to make now, or nullopt: nothing differs, the MC
//    is busy (a remote command or an earlier write runs; the latest value is written when it is
//    free, intermediate ramp steps are skipped, never queued), or a failed write of that kind
//    waits `retry_after`. At most one write is outstanding: next() returns nullopt until
//    on_result() has been called for the previous one.
//  * Speed limit: the target is the SpeedAuthority's limit in force (speed_authority.h): the
//    minimum of the operator's cap, this zone demand (handed to the authority at every next())
//    and the bike's own limit -- so a zone never lifts an operator's lower cap, and leaving a
//    zone restores exactly what is in force without it. It is written only while the authority
//    manages() the limit and only when it differs from the limit the MC reports
//    (mc.speed_limit_kmh; when unknown, the last limit confirmed by a write, else the own
//    limit).
//  * Assist: the cap (percent) allows the levels up to floor(cap / 100 * (n - 1)) of
//    `assist_levels` (ascending, the first one "off"). A current level above that (or not in
//    the list, e.g. "walk") is lowered to the highest allowed one; the level before the first
//    lowering is remembered and written back when the cap returns to 100 -- unless the rider
//    changed the level since (then theirs stays).
//  * on_result(succeeded, now): a success is what the MC confirmed (McActionRunner confirms from
//    the bus); a failure keeps the previous state and delays the next write of that kind.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "gateway/geofence/speed_authority.h"
#include "gateway/geofence/zone_engine.h"

namespace fleetgw::geofence {

struct McView {
  std::optional<int> speed_limit_kmh;       // in force, from the settings report; nullopt unknown
  std::optional<std::string> assist_level;  // current, from the running data; nullopt unknown
  bool busy = false;                        // an MC action is running
};

struct McWrite {
  enum class Kind : std::uint8_t { kSpeedLimit, kAssistLevel };
  Kind kind = Kind::kSpeedLimit;
  int speed_limit_kmh = 0;   // kSpeedLimit
  std::string assist_level;  // kAssistLevel
  friend bool operator==(const McWrite&, const McWrite&) = default;
};

struct EnforcerConfig {
  std::vector<std::string> assist_levels{"off", "eco", "norm", "sport", "turbo"};
  int own_limit_kmh = 25;
  Micros retry_after = 5s;
  // The bike's one authority, shared with the operator's speed-limit commands (the command
  // service's; it must outlive the enforcer). nullptr: the enforcer keeps one of its own with
  // `own_limit_kmh` (no operator cap).
  SpeedAuthority* speed = nullptr;
};

class ZoneEnforcer {
 public:
  explicit ZoneEnforcer(EnforcerConfig config = {})
      : config_(std::move(config)), own_speed_(config_.own_limit_kmh) {}

  std::optional<McWrite> next(const Demands& demands, const McView& mc, Micros now);
  void on_result(bool succeeded, Micros now);

  // The last limit a write of the enforcer set (nullopt: none confirmed yet).
  std::optional<int> applied_limit() const { return applied_limit_; }
  SpeedAuthority& speed() { return config_.speed != nullptr ? *config_.speed : own_speed_; }

 private:
  std::optional<McWrite> next_speed(const McView& mc, Micros now);
  std::optional<McWrite> next_assist(const Demands& demands, const McView& mc, Micros now);
  std::size_t level_index(const std::string& name) const;

  EnforcerConfig config_;
  std::optional<McWrite> outstanding_;
  // Speed limit.
  SpeedAuthority own_speed_;  // used when config_.speed is nullptr
  std::optional<int> applied_limit_;
  Micros speed_retry_at_{0};
  // Assist.
  std::optional<std::string> restore_level_;  // set while the level is lowered
  std::optional<std::string> written_level_;
  Micros assist_retry_at_{0};
};

}  // namespace fleetgw::geofence
