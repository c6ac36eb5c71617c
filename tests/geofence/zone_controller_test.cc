// ZoneController: the whole road as the runtime will drive it -- a signed bundle received and
// stored, a ride into a slow zone and out (the MC writes along the ramp and back), a restart
// that enforces the stored zones offline, and a forged update that changes nothing.
#include "gateway/geofence/zone_controller.h"

#include <gtest/gtest.h>

#include "fleetgw/v1/zones.pb.h"
#include "tests/geofence/zone_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

using namespace testing;
using std::chrono::milliseconds;
using std::chrono::seconds;

const Micros kStart = seconds(1'790'000'000);

class ZoneControllers : public ::testing::Test {
 protected:
  fleetgw::testing::TempDir dir{"zone-controller"};
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();

  ZoneControllerConfig config() {
    ZoneControllerConfig c;
    c.engine.min_dwell = seconds(2);
    c.engine.speed_ramp = seconds(10);
    c.engine.restore_ramp = seconds(5);
    c.trusted_keys = {{"ops", key.public_key().base64()}};
    c.bundle_file = dir / "zones.pb";
    return c;
  }
  std::string signed_slow_zone(std::uint64_t version, std::uint32_t kmh) {
    v1::ZoneBundle b;
    b.set_version(version);
    b.set_issued_at_us(kStart.count());
    add_zone(b, "old-town", v1::ZONE_KIND_SLOW, {rect(-300, -300, 300, 300)}, kmh);
    return sign_zone_bundle(b, key, "ops");
  }
  static std::span<const std::uint8_t> bytes(const std::string& s) {
    return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
  }
};

// Rides from x = -600 m to the centre at 5 m/s, one fix per second, driving the MC as the
// runtime would (ticks every 100 ms, each write confirmed at once); returns the limits the MC
// was given.
std::vector<int> ride(ZoneController& c, McView& mc, Micros& now, double from_x, double to_x,
                      std::vector<ZoneEvent>& events) {
  std::vector<int> writes;
  const double step = to_x > from_x ? 5.0 : -5.0;
  for (double x = from_x; (step > 0 ? x <= to_x : x >= to_x); x += step) {
    const auto fix = fix_at(x, 0, now);
    c.on_position(now, &fix, events);
    for (int i = 0; i < 10; ++i) {
      if (auto w = c.tick(now, mc)) {
        EXPECT_EQ(w->kind, McWrite::Kind::kSpeedLimit);
        writes.push_back(w->speed_limit_kmh);
        mc.speed_limit_kmh = w->speed_limit_kmh;
        c.on_write_result(true, now);
      }
      now += milliseconds(100);
    }
  }
  return writes;
}

TEST_F(ZoneControllers, AStoredBundleSlowsTheBikeAlongTheRampAndSurvivesARestart) {
  Micros now = kStart;
  std::vector<ZoneEvent> events;
  std::string error;
  {
    ZoneController c(config());
    EXPECT_FALSE(c.restore(now, error, events));  // nothing stored yet
    const auto v = c.on_bundle(bytes(signed_slow_zone(1, 15)), now, events, error);
    ASSERT_TRUE(v.accepted()) << v.detail;
    EXPECT_EQ(error, "");
    ASSERT_TRUE(std::filesystem::exists(dir / "zones.pb"));
  }
  // A restart with the broker out of reach: the stored bundle is all there is.
  ZoneController c(config());
  const auto restored = c.restore(now, error, events);
  ASSERT_TRUE(restored && restored->accepted()) << error;
  McView mc{.speed_limit_kmh = 25, .assist_level = "eco"};
  auto writes = ride(c, mc, now, -600, 0, events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].transition, Transition::kEnter);
  EXPECT_EQ(writes, (std::vector<int>{24, 23, 22, 21, 20, 19, 18, 17, 16, 15}));
  // A forged "version 2, 25 km/h" changes nothing.
  auto forged = signed_slow_zone(2, 25);
  forged[forged.size() - 10] ^= 0x01;
  EXPECT_FALSE(c.on_bundle(bytes(forged), now, events, error).accepted());
  EXPECT_EQ(c.demands(now).speed_limit_kmh, 15);
  // Out again: back up to 25 km/h, then nothing more.
  events.clear();
  writes = ride(c, mc, now, 0, -600, events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].transition, Transition::kExit);
  ASSERT_FALSE(writes.empty());
  EXPECT_EQ(writes.back(), 25);
  EXPECT_TRUE(std::is_sorted(writes.begin(), writes.end()));
  EXPECT_FALSE(c.tick(now + seconds(60), mc));
}

TEST_F(ZoneControllers, ANewVersionReplacesTheZonesAndIsStoredForTheNextStart) {
  Micros now = kStart;
  std::vector<ZoneEvent> events;
  std::string error;
  ZoneController c(config());
  ASSERT_TRUE(c.on_bundle(bytes(signed_slow_zone(1, 15)), now, events, error).accepted());
  const auto fix = fix_at(0, 0, now);
  c.on_position(now, &fix, events);
  c.on_position(now + seconds(2), &fix, events);
  ASSERT_EQ(events.size(), 1u);
  ASSERT_TRUE(
      c.on_bundle(bytes(signed_slow_zone(2, 10)), now + seconds(3), events, error).accepted());
  EXPECT_EQ(c.demands(now + seconds(20)).speed_limit_kmh, 10);  // same zone id: still inside
  ZoneController restarted(config());
  const auto v = restarted.restore(now, error, events);
  ASSERT_TRUE(v && v->accepted());
  EXPECT_EQ(restarted.authority().in_force()->zones->version, 2u);
}

}  // namespace
}  // namespace fleetgw::geofence
