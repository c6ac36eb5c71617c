// SpeedAuthority: the one place the bike's speed limit in force is decided (issue 24). Before
// it, an operator's speed-limit command wrote its value to the MC and a slow zone wrote its own
// and remembered "what was there" on entry: whichever wrote last won, so a zone exit restored
// the bike's own 25 km/h over an operator's 20, and operator commands inside a 12 km/h zone
// raised the limit for a moment. Now both only say what they want here, and the MC is given the
// minimum.
//
// Contract:
//  * in_force() = min(operator cap, zone demand, own limit), each term when present (nullopt
//    when none is). The operator's cap is set by a successful speed-limit command (and restored
//    from the store at first use: command_mc.cc); the zone demand is the engine's (ramped)
//    speed demand, refreshed by the enforcer at every tick; the own limit is `[geofence]
//    own_limit_kmh`, the bike's own maximum (absent with geofences off: the MC's factory limit
//    bounds a cap then). Pure logic: no clock, no bus, no I/O.
//  * manages(): once a cap or a zone demand was ever present, the gateway owns the limit and
//    keeps the MC at in_force() (the own limit when both are gone). Before that the MC's limit
//    is left alone (a limit set before this version is not overwritten at start-up).
//  * Slow zones the bike is inside are named from the engine's enter/exit events (on_zone_event)
//    so an operator's result says why ("capped at 20; 12 in force inside 'Old Town'"). The
//    caller passes the name display-safe (the runtime: common::untrusted_excerpt): a bundle's
//    name is signed but still received text, and this library stays free of the text helpers.
//  * explain() / explain_with_cap(): one line, e.g. "capped at 20; 12 in force inside 'Old
//    Town'", "capped at 20; 20 in force", "capped at 30; 25 in force (the bike's own limit)",
//    "no operator cap; 14 in force (restoring after a slow zone)".
#pragma once

#include <map>
#include <optional>
#include <string>

#include "gateway/geofence/zone_engine.h"

namespace fleetgw::geofence {

class SpeedAuthority {
 public:
  explicit SpeedAuthority(std::optional<int> own_limit_kmh) : own_limit_(own_limit_kmh) {}

  void set_own_limit(std::optional<int> kmh) { own_limit_ = kmh; }
  std::optional<int> own_limit() const { return own_limit_; }

  void set_operator_cap(std::optional<int> kmh);
  std::optional<int> operator_cap() const { return cap_; }

  void set_zone_demand(std::optional<int> kmh);
  std::optional<int> zone_demand() const { return zone_demand_; }
  // Slow-zone enter/exit events name the zones the demand comes from (other kinds ignored);
  // `display_name`: e.zone_name made display-safe by the caller.
  void on_zone_event(const ZoneEvent& e, std::string display_name);

  std::optional<int> in_force() const { return in_force_with_cap(cap_); }
  // What would be in force with `cap` as the operator's cap (a command not yet confirmed).
  std::optional<int> in_force_with_cap(std::optional<int> cap) const;
  bool manages() const { return managed_; }

  std::string explain() const { return explain_with_cap(cap_); }
  std::string explain_with_cap(std::optional<int> cap) const;

 private:
  struct SlowZone {
    std::string name;  // display-safe (the caller's)
    int limit_kmh = 0;
  };
  std::optional<int> own_limit_;
  std::optional<int> cap_;
  std::optional<int> zone_demand_;
  std::map<std::string, SlowZone, std::less<>> slow_zones_;  // by zone id, while inside
  bool managed_ = false;
};

}  // namespace fleetgw::geofence
