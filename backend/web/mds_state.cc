// The MDS micromobility state machine (mds_state.h).
#include "backend/web/mds_state.h"

#include <algorithm>

namespace fleetgw::web {

std::string MdsMachine::state() const {
  if (c_.removed) return "removed";
  if (c_.missing) return "missing";
  if (c_.offline) return "non_contactable";
  if (c_.on_trip) return c_.outside ? "elsewhere" : "on_trip";
  if (c_.outside) return "elsewhere";
  if (c_.theft || c_.low_battery) return "non_operational";
  if (c_.reserved) return "reserved";
  return "available";
}

std::optional<MdsEvent> MdsMachine::apply(const MdsSignal& s) {
  const std::string before = state();
  const bool was_missing = c_.missing;
  const std::string trip_before = c_.trip_id;
  std::vector<std::string> types;
  switch (s.kind) {
    case MdsSignalKind::TripStart:
      c_.on_trip = true;
      c_.reserved = false;  // the rider who held it took it
      c_.trip_id = s.trip_id;
      types = {"trip_start"};
      break;
    case MdsSignalKind::TripEnd:
      c_.on_trip = false;
      c_.trip_id = s.trip_id.empty() ? trip_before : s.trip_id;
      types = {"trip_end"};
      break;
    case MdsSignalKind::LeaveArea:
      c_.outside = true;
      types = {c_.on_trip ? "trip_leave_jurisdiction" : "unspecified"};
      break;
    case MdsSignalKind::EnterArea:
      c_.outside = false;
      types = {c_.on_trip ? "trip_enter_jurisdiction" : "unspecified"};
      break;
    case MdsSignalKind::TheftRaised:
      c_.theft = true;
      types = {"unspecified"};
      break;
    case MdsSignalKind::TheftCleared:
      c_.theft = false;
      types = {"unspecified"};
      break;
    case MdsSignalKind::BatteryLow:
      c_.low_battery = true;
      types = {"battery_low"};
      break;
    case MdsSignalKind::BatteryOk:
      c_.low_battery = false;
      types = {"battery_charged"};
      break;
    case MdsSignalKind::CommsLost:
      if (!c_.offline) c_.offline_since_us = s.at_us;
      c_.offline = true;
      types = {"comms_lost"};
      break;
    case MdsSignalKind::CommsRestored:
      c_.offline = false;
      c_.missing = false;
      types = {was_missing ? "located" : "comms_restored"};
      break;
    case MdsSignalKind::Removed:
      c_.removed = true;
      types = {"decommissioned"};
      break;
    case MdsSignalKind::ReservationStart:
      c_.reserved = true;
      types = {"reservation_start"};
      break;
    case MdsSignalKind::ReservationEnd:
      c_.reserved = false;
      types = {"reservation_cancel"};
      break;
  }
  const std::string after = state();
  const std::string trip_now = c_.trip_id;
  if (s.kind == MdsSignalKind::TripEnd) c_.trip_id.clear();
  if (after == before) return std::nullopt;
  // A trip that ends on a low battery (or with a theft alarm active) lands on non_operational:
  // [trip_end, battery_low] (MDS discards the intermediate available).
  if (s.kind == MdsSignalKind::TripEnd && after == "non_operational") {
    types.push_back(c_.theft ? "unspecified" : "battery_low");
  }
  MdsEvent e{s.at_us, after, std::move(types), "", s.place};
  if (e.types.front().starts_with("trip_")) {
    e.trip_id = s.kind == MdsSignalKind::TripStart || s.kind == MdsSignalKind::TripEnd
                    ? trip_now
                    : trip_before;
  }
  return e;
}

std::optional<MdsEvent> MdsMachine::advance_to(std::int64_t at_us, const MdsPlace& place) {
  if (!c_.offline || c_.missing || c_.removed || missing_after_us_ <= 0) return std::nullopt;
  const std::int64_t due = c_.offline_since_us + missing_after_us_;
  if (at_us < due) return std::nullopt;
  c_.missing = true;
  return MdsEvent{due, state(), {"not_located"}, "", place};
}

std::vector<MdsEvent> derive_events(const MdsConditions& start, std::vector<MdsSignal> signals,
                                    std::int64_t missing_after_us, std::int64_t until_us) {
  std::stable_sort(signals.begin(), signals.end(),
                   [](const MdsSignal& a, const MdsSignal& b) { return a.at_us < b.at_us; });
  MdsMachine m(start, missing_after_us);
  std::vector<MdsEvent> out;
  MdsPlace last_place;
  for (const MdsSignal& s : signals) {
    if (auto e = m.advance_to(s.at_us, last_place)) out.push_back(std::move(*e));
    if (auto e = m.apply(s)) out.push_back(std::move(*e));
    if (s.place.lat && s.place.lon) last_place = s.place;
  }
  if (auto e = m.advance_to(until_us, last_place)) out.push_back(std::move(*e));
  return out;
}

}  // namespace fleetgw::web
