// [geofence] in the configuration: its defaults, its values, and the mistakes check-config
// reports (geofences without a position, no bundle file, values out of range).
#include <gtest/gtest.h>

#include "gateway/config/config.h"

namespace fleetgw::config {
namespace {

std::vector<std::string> geofence_problems(const std::string& toml) {
  try {
    parse_config(toml, "zones.toml");
  } catch (const ConfigError& e) {
    return e.problems;
  }
  return {};
}

TEST(GeofenceConfig, DefaultsAreOffAndTheValuesAreRead) {
  const Config d = parse_config("", "empty.toml");
  EXPECT_FALSE(d.geofence.enabled);
  EXPECT_EQ(d.geofence.bundle_file, "/var/lib/fleetgw/zones.pb");
  const Config c = parse_config(
      "[gnss]\nenabled = true\n[geofence]\nenabled = true\nbundle_file = \"/tmp/z.pb\"\n"
      "margin_m = 7.5\nmin_dwell_ms = 1000\nspeed_ramp_ms = 20000\nassist_fade_ms = 4000\n"
      "restore_ramp_ms = 0\nown_limit_kmh = 32\nrefuse_ride_ending_locks = true\n",
      "zones.toml");
  EXPECT_TRUE(c.geofence.enabled);
  EXPECT_EQ(c.geofence.bundle_file, "/tmp/z.pb");
  EXPECT_DOUBLE_EQ(c.geofence.margin_m, 7.5);
  EXPECT_EQ(c.geofence.min_dwell_ms, 1000);
  EXPECT_EQ(c.geofence.speed_ramp_ms, 20000);
  EXPECT_EQ(c.geofence.assist_fade_ms, 4000);
  EXPECT_EQ(c.geofence.restore_ramp_ms, 0);
  EXPECT_EQ(c.geofence.own_limit_kmh, 32);
  EXPECT_TRUE(c.geofence.refuse_ride_ending_locks);
}

TEST(GeofenceConfig, MistakesAreNamedWithFileLineAndKey) {
  auto p = geofence_problems("[geofence]\nenabled = true\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NE(p[0].find("geofence.enabled"), std::string::npos) << p[0];
  EXPECT_NE(p[0].find("enable [gnss]"), std::string::npos) << p[0];
  p = geofence_problems("[gnss]\nenabled = true\n[geofence]\nenabled = true\nbundle_file = \"\"\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NE(p[0].find("zones.toml:5: geofence.bundle_file"), std::string::npos) << p[0];
  p = geofence_problems("[geofence]\nmargin_m = -1\nown_limit_kmh = 0\nzones = 3\n");
  ASSERT_EQ(p.size(), 3u);
  EXPECT_NE(p[0].find("geofence.margin_m"), std::string::npos) << p[0];
  EXPECT_NE(p[1].find("geofence.own_limit_kmh"), std::string::npos) << p[1];
  EXPECT_NE(p[2].find("geofence.zones: unknown key"), std::string::npos) << p[2];
}

}  // namespace
}  // namespace fleetgw::config
