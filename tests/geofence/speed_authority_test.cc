// SpeedAuthority (issue 24): the limit in force is min(operator cap, zone demand, own limit) in
// every order of events, and an operator's result says which limit is in force and why.
#include "gateway/geofence/speed_authority.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <string>

#include "gateway/geofence/zone_enforcer.h"

namespace fleetgw::geofence {
namespace {

using std::chrono::seconds;

const Micros kEpoch = seconds(1'790'000'000);

ZoneEvent slow(std::string id, std::string name, int kmh, Transition t) {
  ZoneEvent e;
  e.zone_id = std::move(id);
  e.zone_name = std::move(name);
  e.kind = ZoneKind::kSlow;
  e.transition = t;
  e.speed_limit_kmh = kmh;
  return e;
}

TEST(SpeedAuthority, TheLimitInForceIsTheMinimumOfWhatIsPresent) {
  SpeedAuthority a(25);
  EXPECT_EQ(a.in_force(), 25);
  EXPECT_FALSE(a.manages());
  a.set_operator_cap(30);  // above the bike's own limit: the own limit holds
  EXPECT_EQ(a.in_force(), 25);
  EXPECT_TRUE(a.manages());
  EXPECT_EQ(a.explain(), "capped at 30; 25 in force (the bike's own limit)");
  a.set_operator_cap(20);
  EXPECT_EQ(a.in_force(), 20);
  EXPECT_EQ(a.explain(), "capped at 20; 20 in force");
  a.on_zone_event(slow("old-town", "Old Town", 12, Transition::kEnter), "Old Town");
  a.set_zone_demand(12);
  EXPECT_EQ(a.in_force(), 12);
  EXPECT_EQ(a.explain(), "capped at 20; 12 in force inside 'Old Town'");
  EXPECT_EQ(a.in_force_with_cap(25), 12);
  EXPECT_EQ(a.explain_with_cap(25), "capped at 25; 12 in force inside 'Old Town'");
  EXPECT_EQ(a.in_force_with_cap(10), 10);
  EXPECT_EQ(a.explain_with_cap(10), "capped at 10; 10 in force");
  // Without [geofence] there is no own limit: the cap alone (the MC's range bounds it).
  SpeedAuthority bare(std::nullopt);
  EXPECT_EQ(bare.in_force(), std::nullopt);
  EXPECT_EQ(bare.explain(), "no operator cap; the MC's own limit in force");
  bare.set_operator_cap(40);
  EXPECT_EQ(bare.in_force(), 40);
}

TEST(SpeedAuthority, TheResultNamesTheLowestZoneTheRampAndTheRestore) {
  SpeedAuthority a(25);
  a.on_zone_event(slow("a", "Old Town", 15, Transition::kEnter), "Old Town");
  // The caller escapes the name (the runtime: common::untrusted_excerpt).
  a.on_zone_event(slow("b", "School\nStreet", 10, Transition::kEnter), "School\\nStreet");
  a.set_zone_demand(18);  // the ramp on its way down
  EXPECT_EQ(a.explain(), "no operator cap; 18 in force inside 'School\\nStreet' (slowing to 10)");
  a.set_zone_demand(10);
  EXPECT_EQ(a.explain(), "no operator cap; 10 in force inside 'School\\nStreet'");
  a.on_zone_event(slow("b", "School\nStreet", 10, Transition::kExit), "School\nStreet");
  a.on_zone_event(slow("a", "Old Town", 15, Transition::kExit), "Old Town");
  a.set_zone_demand(20);  // the restore ramp after the last zone
  EXPECT_EQ(a.explain(), "no operator cap; 20 in force (restoring after a slow zone)");
  a.set_zone_demand(std::nullopt);
  EXPECT_EQ(a.explain(), "no operator cap; 25 in force (the bike's own limit)");
  EXPECT_TRUE(a.manages());  // the gateway keeps the limit it decided
}

// Every order of "operator caps at 20", "enters the 12 km/h zone" and "leaves it" (the zone
// ramps instantly here), driven through the enforcer against an MC that takes each write: the
// MC is never above the cap once it is set, never above 12 inside the zone, and ends at exactly
// the minimum of what is left.
TEST(SpeedAuthority, EveryOrderOfCapZoneAndExitEndsAtTheMinimumAndNeverOvershoots) {
  enum Event { kCap, kEnter, kExit };
  std::array<Event, 3> order{kCap, kEnter, kExit};
  int orders = 0;
  do {
    SCOPED_TRACE(::testing::Message() << "order " << order[0] << order[1] << order[2]);
    SpeedAuthority a(25);
    ZoneEnforcer e(EnforcerConfig{.speed = &a});
    McView mc{.speed_limit_kmh = 25, .assist_level = "eco"};
    std::optional<int> demand;
    bool inside = false;
    bool capped = false;
    auto settle = [&] {
      for (int i = 0; i < 5; ++i) {
        Demands d;
        d.speed_limit_kmh = demand;
        if (const auto w = e.next(d, mc, kEpoch)) {
          mc.speed_limit_kmh = w->speed_limit_kmh;
          e.on_result(true, kEpoch);
        }
        if (capped) {
          EXPECT_LE(*mc.speed_limit_kmh, 20);
        }
        if (inside) {
          EXPECT_LE(*mc.speed_limit_kmh, 12);
        }
      }
    };
    for (const Event ev : order) {
      switch (ev) {
        case kCap:
          // What the command writes is the authority's minimum with the new cap; then recorded.
          mc.speed_limit_kmh = a.in_force_with_cap(20);
          a.set_operator_cap(20);
          capped = true;
          break;
        case kEnter:
          a.on_zone_event(slow("old-town", "Old Town", 12, Transition::kEnter), "Old Town");
          demand = 12;
          inside = true;
          break;
        case kExit:
          // An exit before the entry is a no-op (the engine never emits one; harmless here).
          if (inside)
            a.on_zone_event(slow("old-town", "Old Town", 12, Transition::kExit), "Old Town");
          demand.reset();
          inside = false;
          break;
      }
      settle();
    }
    int expected = 25;
    if (capped) expected = std::min(expected, 20);
    if (inside) expected = std::min(expected, 12);
    EXPECT_EQ(mc.speed_limit_kmh, expected);
    EXPECT_EQ(a.in_force(), expected);
    ++orders;
  } while (std::next_permutation(order.begin(), order.end()));
  EXPECT_EQ(orders, 6);
}

}  // namespace
}  // namespace fleetgw::geofence
