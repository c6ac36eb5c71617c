// The MDS 2.0 micromobility state machine over fleetgw's signals (pure: no database), used by
// mds_api.cc for events and vehicle status. docs/standards.md has the table.
//
// Contract:
//  * A vehicle's conditions (on a trip, outside the operating area, a theft-class alarm active,
//    battery low, out of contact, removed) come from signals applied in time order; the state
//    is a function of them, highest first: removed; missing (out of contact for longer than
//    missing_after_us); non_contactable; on a trip: elsewhere when outside, else on_trip; parked
//    outside: elsewhere; theft alarm or low battery: non_operational; reserved; else available.
//    A trip start ends a reservation (reserved -> on_trip).
//  * apply() returns the event when the state changes (never otherwise), typed by the signal:
//    trip_start, trip_end (with battery_low after it when the trip ends on a low battery),
//    trip_leave_jurisdiction / trip_enter_jurisdiction (on a trip), battery_low,
//    battery_charged, comms_lost, comms_restored (located from missing), not_located,
//    decommissioned, reservation_start, reservation_cancel (MDS 2.0 has no reservation_stop:
//    a cancelled or expired reservation is reservation_cancel); unspecified for a theft alarm
//    raised or cleared and a parked vehicle crossing the area's edge (MDS has no type for them).
//    Trip events carry the trip's id.
//  * advance_to(t) emits not_located when the vehicle has been out of contact for
//    missing_after_us by t.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fleetgw::web {

enum class MdsSignalKind {
  TripStart,
  TripEnd,
  LeaveArea,
  EnterArea,
  TheftRaised,
  TheftCleared,
  BatteryLow,
  BatteryOk,
  CommsLost,
  CommsRestored,
  Removed,
  ReservationStart,
  ReservationEnd,  // cancelled or expired (a trip start ends it too, without this signal)
};

struct MdsPlace {
  std::optional<double> lat;
  std::optional<double> lon;
  std::optional<int> soc_pct;
};

struct MdsSignal {
  std::int64_t at_us = 0;
  MdsSignalKind kind = MdsSignalKind::TripStart;
  std::string trip_id;  // TripStart/TripEnd
  MdsPlace place;
};

struct MdsEvent {
  std::int64_t at_us = 0;
  std::string state;
  std::vector<std::string> types;
  std::string trip_id;  // empty: none
  MdsPlace place;
};

// The conditions at a moment (the start of a window), from the latest rows before it.
struct MdsConditions {
  bool on_trip = false;
  std::string trip_id;
  bool outside = false;
  bool theft = false;
  bool low_battery = false;
  bool offline = false;
  std::int64_t offline_since_us = 0;
  bool missing = false;
  bool removed = false;
  bool reserved = false;  // an operator's reservation in force (registry_reservations.h)
};

class MdsMachine {
 public:
  MdsMachine(MdsConditions start, std::int64_t missing_after_us)
      : c_(std::move(start)), missing_after_us_(missing_after_us) {}

  std::string state() const;
  const MdsConditions& conditions() const { return c_; }
  std::optional<MdsEvent> apply(const MdsSignal& s);
  std::optional<MdsEvent> advance_to(std::int64_t at_us, const MdsPlace& place);

 private:
  MdsConditions c_;
  std::int64_t missing_after_us_;
};

// The events of `signals` (any order; sorted by time, ties in the given order) from `start`,
// with not_located checked before each signal and at until_us.
std::vector<MdsEvent> derive_events(const MdsConditions& start, std::vector<MdsSignal> signals,
                                    std::int64_t missing_after_us, std::int64_t until_us);

}  // namespace fleetgw::web
