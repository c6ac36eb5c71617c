// The MDS 2.0 micromobility state machine (issue 27, backend/web/mds_state.h): every transition
// it emits must be one of the state-transition table of MDS 2.0's modes/micromobility.md.
#include <gtest/gtest.h>

#include <set>
#include <tuple>

#include "backend/web/mds_state.h"

namespace fleetgw::web {
namespace {

using Sig = MdsSignalKind;

// (from, to, event_type) rows of MDS 2.0's micromobility table that this machine can produce;
// non_contactable and missing transitions are given by the table's prose (any state to
// non_contactable with comms_lost, non_contactable to any state with comms_restored, missing to
// any state with located).
bool allowed(const std::string& from, const std::string& to, const std::string& type) {
  static const std::set<std::tuple<std::string, std::string, std::string>> table = {
      {"available", "non_operational", "battery_low"},
      {"available", "non_operational", "unspecified"},
      {"non_operational", "available", "battery_charged"},
      {"non_operational", "available", "unspecified"},
      {"available", "on_trip", "trip_start"},
      {"reserved", "on_trip", "trip_start"},
      {"available", "reserved", "reservation_start"},
      {"reserved", "available", "reservation_cancel"},
      {"on_trip", "available", "trip_end"},
      {"on_trip", "elsewhere", "trip_leave_jurisdiction"},
      {"elsewhere", "on_trip", "trip_enter_jurisdiction"},
      {"non_contactable", "missing", "not_located"},
      {"available", "removed", "decommissioned"},
      {"non_operational", "removed", "decommissioned"},
      {"elsewhere", "removed", "decommissioned"},
  };
  if (type == "comms_lost") return to == "non_contactable";
  if (type == "comms_restored") return from == "non_contactable";
  if (type == "located") return from == "missing";
  return table.contains({from, to, type});
}

MdsSignal sig(std::int64_t at, Sig k, std::string trip = "") {
  return {at, k, std::move(trip), {48.1, 11.5, 80}};
}

// Walks the events, checking each against the table from the state before it.
void expect_valid_walk(const std::vector<MdsEvent>& events, std::string state = "available") {
  for (const MdsEvent& e : events) {
    ASSERT_FALSE(e.types.empty());
    if (e.types.size() == 2 && e.types[0] == "trip_end") {
      // Two ordered types pass through the intermediate state (MDS discards it): available.
      EXPECT_TRUE(allowed(state, "available", "trip_end")) << state;
      EXPECT_TRUE(allowed("available", e.state, e.types[1])) << e.state << " by " << e.types[1];
    } else {
      ASSERT_EQ(e.types.size(), 1u);
      EXPECT_TRUE(allowed(state, e.state, e.types.front()))
          << state << " -> " << e.state << " by " << e.types.front();
    }
    const bool trip = e.types.front().starts_with("trip_");
    EXPECT_EQ(trip, !e.trip_id.empty()) << e.types.front() << " trip_ids";
    state = e.state;
  }
}

std::vector<std::string> states(const std::vector<MdsEvent>& events) {
  std::vector<std::string> out;
  for (const MdsEvent& e : events) out.push_back(e.state + ":" + e.types.front());
  return out;
}

TEST(MdsState, RideThroughTheEdgeOfTheOperatingArea) {
  const auto events = derive_events({},
                                    {sig(10, Sig::TripStart, "t1"), sig(20, Sig::LeaveArea),
                                     sig(30, Sig::EnterArea), sig(40, Sig::TripEnd, "t1")},
                                    0, 100);
  EXPECT_EQ(states(events),
            (std::vector<std::string>{"on_trip:trip_start", "elsewhere:trip_leave_jurisdiction",
                                      "on_trip:trip_enter_jurisdiction", "available:trip_end"}));
  expect_valid_walk(events);
  for (const MdsEvent& e : events) EXPECT_EQ(e.trip_id, "t1");
}

TEST(MdsState, TripEndingOnALowBatteryIsTripEndThenBatteryLow) {
  const auto events = derive_events({},
                                    {sig(10, Sig::TripStart, "t1"), sig(20, Sig::BatteryLow),
                                     sig(30, Sig::TripEnd, "t1"), sig(40, Sig::BatteryOk)},
                                    0, 100);
  ASSERT_EQ(events.size(), 3u);  // battery_low during the trip changes no state
  EXPECT_EQ(events[1].state, "non_operational");
  EXPECT_EQ(events[1].types, (std::vector<std::string>{"trip_end", "battery_low"}));
  EXPECT_EQ(events[2].state, "available");
  EXPECT_EQ(events[2].types.front(), "battery_charged");
  expect_valid_walk(events);
}

TEST(MdsState, TheftAlarmTakesTheBikeOutOfServiceUntilCleared) {
  const auto events =
      derive_events({}, {sig(10, Sig::TheftRaised), sig(20, Sig::TheftCleared)}, 0, 100);
  EXPECT_EQ(states(events),
            (std::vector<std::string>{"non_operational:unspecified", "available:unspecified"}));
  expect_valid_walk(events);
}

TEST(MdsState, LostContactBecomesMissingAfterADayThenLocated) {
  constexpr std::int64_t kDay = 86'400'000'000;
  const auto events = derive_events(
      {}, {sig(10, Sig::CommsLost), sig(10 + 2 * kDay, Sig::CommsRestored)}, kDay, 3 * kDay);
  EXPECT_EQ(states(events), (std::vector<std::string>{"non_contactable:comms_lost",
                                                      "missing:not_located", "available:located"}));
  EXPECT_EQ(events[1].at_us, 10 + kDay);
  expect_valid_walk(events);
}

TEST(MdsState, ConditionsAtTheWindowStartCarryOver) {
  MdsConditions start;
  start.on_trip = true;
  start.trip_id = "t0";
  const auto events = derive_events(start, {sig(5, Sig::TripEnd, "t0")}, 0, 100);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].types.front(), "trip_end");
  EXPECT_EQ(events[0].trip_id, "t0");
  expect_valid_walk(events, "on_trip");
}

TEST(MdsState, RedundantSignalsEmitNothing) {
  const auto events = derive_events(
      {}, {sig(10, Sig::BatteryOk), sig(20, Sig::EnterArea), sig(30, Sig::TheftCleared)}, 0, 100);
  EXPECT_TRUE(events.empty());
}

TEST(MdsState, RemovedIsFinal) {
  const auto events = derive_events({}, {sig(10, Sig::Removed), sig(20, Sig::BatteryLow)}, 0, 100);
  EXPECT_EQ(states(events), (std::vector<std::string>{"removed:decommissioned"}));
  expect_valid_walk(events);
}

// Reservations (registry_reservations.h): reserved by reservation_start, back to available by
// reservation_cancel (cancelled or expired), or on_trip when the rider takes the bike -- and
// the reservation's later end then changes nothing.
TEST(MdsState, AReservationEndsByCancelOrByTheTripThatTakesTheBike) {
  auto events =
      derive_events({}, {sig(10, Sig::ReservationStart), sig(20, Sig::ReservationEnd)}, 0, 100);
  EXPECT_EQ(states(events), (std::vector<std::string>{"reserved:reservation_start",
                                                      "available:reservation_cancel"}));
  expect_valid_walk(events);
  events = derive_events({},
                         {sig(10, Sig::ReservationStart), sig(20, Sig::TripStart, "t1"),
                          sig(30, Sig::TripEnd, "t1"), sig(40, Sig::ReservationEnd)},
                         0, 100);
  EXPECT_EQ(states(events), (std::vector<std::string>{"reserved:reservation_start",
                                                      "on_trip:trip_start", "available:trip_end"}));
  expect_valid_walk(events);
  // Reserved at the window's start: cancelled within it.
  MdsConditions start;
  start.reserved = true;
  events = derive_events(start, {sig(5, Sig::ReservationEnd)}, 0, 100);
  EXPECT_EQ(states(events), (std::vector<std::string>{"available:reservation_cancel"}));
  expect_valid_walk(events, "reserved");
}

}  // namespace
}  // namespace fleetgw::web
