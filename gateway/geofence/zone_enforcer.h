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
//  * Speed limit: on the first zone limit, the limit in force (mc.speed_limit_kmh, from the MC's
//    settings report; `own_limit_kmh` when unknown) is remembered; the target is the zone
//    limit, never above that remembered limit (an operator's lower cap is not raised). When the
//    demands no longer carry a limit, the remembered limit is written back once, and the
//    enforcer forgets it. A limit the MC already reports is not written again.
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
};

class ZoneEnforcer {
 public:
  explicit ZoneEnforcer(EnforcerConfig config = {}) : config_(std::move(config)) {}

  std::optional<McWrite> next(const Demands& demands, const McView& mc, Micros now);
  void on_result(bool succeeded, Micros now);

  // The limit the enforcer has written and not yet restored (nullopt: none).
  std::optional<int> applied_limit() const { return applied_limit_; }

 private:
  std::optional<McWrite> next_speed(const Demands& demands, const McView& mc, Micros now);
  std::optional<McWrite> next_assist(const Demands& demands, const McView& mc, Micros now);
  std::size_t level_index(const std::string& name) const;

  EnforcerConfig config_;
  std::optional<McWrite> outstanding_;
  // Speed limit.
  std::optional<int> restore_limit_;  // set while a zone limit is applied
  std::optional<int> applied_limit_;
  Micros speed_retry_at_{0};
  // Assist.
  std::optional<std::string> restore_level_;  // set while the level is lowered
  std::optional<std::string> written_level_;
  Micros assist_retry_at_{0};
};

}  // namespace fleetgw::geofence
