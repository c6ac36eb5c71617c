// The retained last-known state of the vehicle (fleetgw.v1.VehicleState, proto/fleetgw/v1/
// state.proto, topic <prefix>/<vehicle>/state): what it is built from, and when it is rebuilt.
//
// Contract:
//  * build_vehicle_state() is a pure function of its inputs: the serialized VehicleState body
//    (not an Envelope), units per the unit rule, absent values absent. `online` is left false:
//    the uplink sets it when it publishes (it alone knows the connection).
//  * StateThrottle decides WHEN, on the wall clock, without a periodic timer: touch() says the
//    inputs may have changed (frames, an alarm, a position); deadline() is then the earliest
//    moment a check is allowed (the last publish + min_interval, at once for the first); a
//    check (offer()) hands the state over only when it differs from the last one handed over
//    (updated_at_us ignored). Nothing touched = no deadline, so an idle gateway never wakes
//    for it. min_interval 0 disables the state altogether (deadline() always nullopt).
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fleetgw/v1/status.pb.h"
#include "gateway/gnss/position.h"
#include "gateway/runtime/live_state.h"
#include "motinova/can.h"

namespace fleetgw::runtime {

struct VehicleStateInputs {
  const LiveState* live = nullptr;
  std::vector<std::string_view> active_alarms;  // AlarmTracker::active_kinds()
  // The geofence's outside_operating_area alarm (not an AlarmTracker alarm), listed after them.
  bool outside_operating_area = false;
  std::optional<gnss::Fix> position;  // the current fix; nullopt = unknown
  std::optional<bool> parked;              // nullopt = not known yet
  fleetgw::v1::BusState bus_state = fleetgw::v1::BUS_STATE_UNSPECIFIED;
  motinova::Micros now{0};  // bus time: updated_at_us
};

// The serialized fleetgw.v1.VehicleState body; with `with_time` false, updated_at_us stays 0
// (the form compared to detect a change).
std::string build_vehicle_state(const VehicleStateInputs& in, bool with_time = true);

// The position as the throttle compares it: a fix within `min_move_m` of the one last handed
// over counts as that one, so GNSS jitter, a new fix time or satellite count of a parked bike do
// not republish the state every interval (with GNSS on, a parked bike's fix changes every
// second); moving further, or the position becoming unknown, does. The published state always
// carries the current fix. min_move_m 0 compares every fix.
class StatePositionFilter {
 public:
  explicit StatePositionFilter(double min_move_m) : min_move_m_(min_move_m) {}
  std::optional<gnss::Fix> comparable(const std::optional<gnss::Fix>& current) const;
  // After a hand-over: the position that was compared (comparable()'s result) is the new anchor.
  void handed_over(const std::optional<gnss::Fix>& compared) { anchor_ = compared; }

 private:
  double min_move_m_;
  std::optional<gnss::Fix> anchor_;
};

class StateThrottle {
 public:
  using Clock = std::chrono::steady_clock;
  explicit StateThrottle(std::chrono::milliseconds min_interval) : min_interval_(min_interval) {}

  bool enabled() const { return min_interval_.count() > 0; }
  void touch() { touched_ = enabled(); }
  std::optional<Clock::time_point> deadline() const;
  bool due(Clock::time_point now) const {
    const auto d = deadline();
    return d && now >= *d;
  }
  // A check at `now`: true (and remembered) when `comparable` differs from the last state
  // handed over; the caller then publishes. Clears the touch either way.
  bool offer(const std::string& comparable, Clock::time_point now);

 private:
  std::chrono::milliseconds min_interval_;
  bool touched_ = false;
  std::optional<Clock::time_point> last_sent_;
  std::string last_;
};

}  // namespace fleetgw::runtime
