// ZoneEngine: geofences evaluated on the bike (issue 14) -- from position fixes to zone
// enter/exit events and to what the motor controller should be told, as values. Pure logic: no
// clock (every entry point takes the wall-clock `now`), no I/O, no bus; the runtime writes the
// demands through the MC command path and stores and publishes the events.
//
// Contract:
//  * Zones come as an immutable ZoneSet (zone_bundle.h builds one from a verified bundle).
//    set_zones() replaces it: a zone id present in both keeps its state; a zone removed while
//    the bike was inside produces an exit event (its effects end).
//  * relocate(now, fix) (a bundle replaced at run time): every zone takes the side `fix` is on
//    at once, without the dwell -- the bike did not cross anything, the zones moved, so there is
//    no crossing to confirm. Events as for step() (unknown -> inside ENTER, inside -> outside
//    EXIT); a fix within a zone's margin leaves that zone as it was.
//  * step(now, fix) takes the CURRENT fix or nullptr (position unknown or stale). Unknown means
//    no transition at all: every zone keeps its state (a slow zone stays applied in a tunnel),
//    and a transition that was pending starts over.
//  * Hysteresis: a fix counts as inside (outside) a zone only when it is inside (outside) by at
//    least `margin_m` from every edge; a fix within the margin counts for neither side. A zone's
//    state changes only after fixes on the other side for at least `min_dwell` without
//    interruption (a fix within the margin, on the old side or unknown interrupts it). So GNSS
//    jitter across a boundary does not flap; a real crossing is reported once the bike is
//    `margin_m` past the boundary for `min_dwell`.
//  * A zone starts in "unknown" state. unknown -> inside is an ENTER event (a bike switched on
//    inside a slow zone gets its limit); unknown -> outside is silent; inside -> outside is an
//    EXIT event. Events carry the fix that decided them.
//  * Demands (demands(now), also returned by step()):
//      - speed_limit_kmh: the lowest limit of the slow zones the bike is inside, reached along a
//        linear ramp of `speed_ramp` from the limit in force when the target changed; after the
//        last slow zone it ramps back up to `unrestricted_kmh` over `restore_ramp`, then is
//        nullopt (no zone limit: the bike's own applies). Whole km/h, rounded so a falling
//        limit never undercuts the ramp and a rising one never overshoots it.
//      - assist_cap_percent: 100 normally; inside a no-ride zone it fades linearly to 0 over
//        `assist_fade` (never an abrupt stop), and back to 100 over `restore_ramp` after it.
//      - outside_operating_area: the bundle has operating areas and the bike is (confirmed)
//        outside every one of them -- the alarm level.
//      - in_no_parking_zone: (confirmed) inside a no-parking zone.
//  * next_change(now) is when demands() next changes without a new fix (a ramp's next whole
//    step), so the owner can wake up for it; nullopt while nothing is moving.
//  * parking(fix, ride_ending) judges a lock at that fix, from the fix itself (a bike locked
//    seconds after entering a zone is still judged where it is): a fix inside a no-parking zone
//    or within the margin of one is reported; the lock is refused only when
//    `refuse_ride_ending_locks`, the lock ends a ride and the fix is inside by at least the
//    margin. An unknown position never refuses a lock (a rider must always be able to end a
//    ride).
//  * Issue 27 (GBFS): a zone's effects are those of its kind, or for a kRules zone those of its
//    first rule for `vehicle_type_id` (none: the zone does not exist for this bike: never
//    located, no events). A zone with a time window [start, end) exists only within it, by the
//    `now` given (the gateway's clock): outside it no events and no effects; a window opening or
//    closing while the bike is inside is an ENTER or EXIT at that instant (advance(now) and
//    every step/relocate), and next_change() includes the next window edge.
//  * Precedence: kUnion (every bundle before issue 27) combines every zone the bike is in (the
//    lowest limit, any no-ride...); kFirstMatch (GBFS) takes only the first zone in bundle order
//    the bike is confirmed inside (operating areas aside), and outside every zone -- each one
//    that exists for the bike confirmed outside -- the bundle's default rules.
//  * A limit of 0 km/h ("stop") fades the assistance to off as a no-ride zone does; the MC is
//    never given 0.
//  * starting(fix, ride_starting, now) judges an unlock as parking() judges a lock, against the
//    no-start effects: refused when it starts a ride and the fix is clearly inside (no
//    configuration: refusing a start strands nobody); an unknown position never refuses.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/geofence/zone_geometry.h"
#include "gateway/gnss/position.h"

namespace fleetgw::geofence {

using Micros = std::chrono::microseconds;
using namespace std::chrono_literals;

// Same numbers as fleetgw.v1.ZoneKind.
enum class ZoneKind : std::uint8_t {
  kOperatingArea = 1,
  kSlow = 2,
  kNoRide = 3,
  kNoParking = 4,
  kNoStart = 5,
  kRules = 6,
};
// "operating_area", "slow", "no_ride", "no_parking", "no_start", "rules".
std::string_view zone_kind_name(ZoneKind kind);

// What a zone (or the default outside every zone) demands of the bike.
struct Effects {
  std::optional<int> speed_limit_kmh;  // 0: stop (the assistance fades to off)
  bool no_ride = false;
  bool no_parking = false;
  bool no_start = false;
  friend bool operator==(const Effects&, const Effects&) = default;
};

// A GBFS rule (fleetgw.v1.ZoneRule): its effects, for which vehicle types (empty: every one).
struct ZoneRuleSpec {
  std::vector<std::string> vehicle_type_ids;
  Effects effects;
  bool applies_to(std::string_view vehicle_type_id) const;
};

struct EnforcedZone {
  std::string id;
  std::string name;
  ZoneKind kind = ZoneKind::kSlow;
  int speed_limit_kmh = 0;  // kSlow only
  ZonePolygon shape;
  std::vector<ZoneRuleSpec> rules{};  // kRules only
  Micros start{0};                    // exists from (0: always)...
  Micros end{0};                      // ...until, exclusive (0: no end)
  bool exists_at(Micros now) const {
    return (start.count() == 0 || now >= start) && (end.count() == 0 || now < end);
  }
  // The effects for a bike of `vehicle_type_id`; nullopt: the zone does not apply to it.
  std::optional<Effects> effects_for(std::string_view vehicle_type_id) const;
};

enum class Precedence : std::uint8_t { kUnion = 0, kFirstMatch = 1 };

struct ZoneSet {
  std::uint64_t version = 0;
  Micros issued_at{0};
  std::vector<EnforcedZone> zones;
  std::size_t vertices = 0;
  Precedence precedence = Precedence::kUnion;
  std::vector<ZoneRuleSpec> default_rules;  // kFirstMatch: outside every zone
};

struct EngineConfig {
  double margin_m = 10.0;
  Micros min_dwell = 3s;
  Micros speed_ramp = 10s;
  Micros assist_fade = 8s;
  Micros restore_ramp = 5s;
  int unrestricted_kmh = 25;  // the bike's own limit: where a restored limit ramps back to
  bool refuse_ride_ending_locks = false;
  std::string vehicle_type_id{};  // [vehicle] type_id: which GBFS rules apply (empty: untyped only)
};

// Same numbers as fleetgw.v1.ZoneTransition.
enum class Transition : std::uint8_t {
  kEnter = 1,
  kExit = 2,
  kLockedInNoParking = 3,
  kLockRefused = 4,
  kUnlockRefused = 5,
};
// "enter", "exit", "locked_in_no_parking", "lock_refused", "unlock_refused".
std::string_view transition_name(Transition t);

struct ZoneEvent {
  std::string zone_id;
  std::string zone_name;
  ZoneKind kind = ZoneKind::kSlow;
  Transition transition = Transition::kEnter;
  Micros at{0};
  std::optional<gnss::Fix> position;  // absent only for a zone removed with no fix known
  std::uint64_t bundle_version = 0;
  int speed_limit_kmh = 0;
};

struct Demands {
  std::optional<int> speed_limit_kmh;
  int assist_cap_percent = 100;
  bool outside_operating_area = false;
  bool in_no_parking_zone = false;
  bool in_no_start_zone = false;
  friend bool operator==(const Demands&, const Demands&) = default;
};

struct ParkingVerdict {
  bool in_no_parking_zone = false;  // report the lock
  bool refuse = false;              // refuse it (ride-ending lock, clearly inside, configured)
  std::optional<ZoneEvent> event;   // kLockedInNoParking or kLockRefused, when in such a zone
};

// A value moving linearly from one level to another over a set duration.
class Ramp {
 public:
  explicit Ramp(double level) : from_(level), to_(level) {}
  // Starts moving from the current value towards `to` (nothing when `to` is already the target).
  void retarget(double to, Micros now, Micros duration);
  double value(Micros now) const;
  double target() const { return to_; }
  bool settled(Micros now) const { return now >= start_ + duration_ || from_ == to_; }
  // The value in whole units: ceil while falling, floor while rising.
  int whole(Micros now) const;
  // When whole() next changes; nullopt once settled.
  std::optional<Micros> next_step(Micros now) const;

 private:
  double from_;
  double to_;
  Micros start_{0};
  Micros duration_{0};
};

class ZoneEngine {
 public:
  explicit ZoneEngine(EngineConfig config = {});

  void set_zones(std::shared_ptr<const ZoneSet> zones, Micros now, std::vector<ZoneEvent>& events);
  Demands step(Micros now, const gnss::Fix* fix, std::vector<ZoneEvent>& events);
  void relocate(Micros now, const gnss::Fix& fix, std::vector<ZoneEvent>& events);
  // Window edges up to `now`: ENTER/EXIT of a zone the bike is inside, new targets.
  void advance(Micros now, std::vector<ZoneEvent>& events);
  Demands demands(Micros now) const;
  std::optional<Micros> next_change(Micros now) const;
  ParkingVerdict parking(const gnss::Fix* fix, bool ride_ending, Micros now) const;
  // An unlock at `fix`: `refuse` when it starts a ride clearly inside a no-start zone.
  ParkingVerdict starting(const gnss::Fix* fix, bool ride_starting, Micros now) const;

  const std::shared_ptr<const ZoneSet>& zones() const { return zones_; }
  const EngineConfig& config() const { return config_; }
  // The confirmed state of zone `index` of zones(): true inside, false outside, nullopt unknown.
  std::optional<bool> inside(std::size_t index) const;

 private:
  enum class Side : std::uint8_t { kUnknown, kInside, kOutside };
  struct State {
    Side confirmed = Side::kUnknown;
    Side pending = Side::kUnknown;
    Micros pending_since{0};
  };
  ZoneEvent event_for(const EnforcedZone& zone, Transition t, Micros now,
                      const std::optional<gnss::Fix>& where) const;
  void update_targets(Micros now);
  // Does zone i take part at `now` (for this bike's type, within its window)?
  bool live(std::size_t i, Micros now) const;
  // The effects in force from the confirmed states (precedence applied).
  Effects effective(Micros now) const;
  // A lock or unlock judged at a fix against one effect (no_parking or no_start).
  struct Judged {
    bool near = false;    // inside or within the margin of a zone with the effect
    bool inside = false;  // clearly inside it (past the margin)
    const EnforcedZone* zone = nullptr;
    bool by_default = false;  // the default rules outside every zone
  };
  Judged judge(const gnss::Fix& fix, Micros now, bool Effects::*effect) const;
  ParkingVerdict verdict_of(const Judged& j, const gnss::Fix& fix, Micros now,
                            Transition reported, Transition refused, bool refuse) const;

  EngineConfig config_;
  std::shared_ptr<const ZoneSet> zones_;
  std::vector<State> states_;
  std::vector<std::optional<Effects>> effects_;  // per zone, for this bike's type
  std::optional<Effects> default_effects_;
  std::vector<bool> existed_;  // per zone: within its window at the last advance()
  std::optional<gnss::Fix> last_fix_;
  Ramp speed_;
  Ramp assist_;
};

}  // namespace fleetgw::geofence
