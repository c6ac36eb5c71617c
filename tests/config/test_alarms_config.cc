// The [alarms] section: defaults match the shipped file, values are read, and mistakes are
// reported with file, line and key.
#include <gtest/gtest.h>

#include "gateway/config/config.h"

namespace fleetgw::config {
namespace {

std::string problems_text(const std::string& text) {
  try {
    parse_config(text, "alarms.toml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return {};
}

TEST(AlarmsConfig, ShippedFileMatchesTheDefaults) {
  const Config file = load_config(FLEETGW_DEFAULT_CONFIG);
  const Config defaults = parse_config("", "empty.toml");
  EXPECT_EQ(file.alarms.low_battery_pct, defaults.alarms.low_battery_pct);
  EXPECT_EQ(file.alarms.movement_debounce_ms, defaults.alarms.movement_debounce_ms);
  EXPECT_EQ(file.alarms.battery_silent_ms, defaults.alarms.battery_silent_ms);
  EXPECT_EQ(defaults.alarms.low_battery_pct, (std::vector<int>{20, 10, 5}));
}

TEST(AlarmsConfig, ValuesAreRead) {
  const Config c = parse_config(
      "[alarms]\nmovement_debounce_ms = 500\nlow_battery_pct = [30, 15]\nenabled = false\n",
      "a.toml");
  EXPECT_EQ(c.alarms.movement_debounce_ms, 500);
  EXPECT_EQ(c.alarms.low_battery_pct, (std::vector<int>{30, 15}));
  EXPECT_FALSE(c.alarms.enabled);
}

TEST(AlarmsConfig, MistakesNameFileLineAndKey) {
  EXPECT_NE(problems_text("[alarms]\nlow_battery_pct = [5, 10]\n")
                .find("alarms.toml:2: alarms.low_battery_pct: expected up to 8 integers"),
            std::string::npos);
  EXPECT_NE(problems_text("[alarms]\nlow_battery_pct = [20, \"x\"]\n").find("low_battery_pct"),
            std::string::npos);
  EXPECT_NE(problems_text("[alarms]\n\nmovement_debounce_ms = -1\n")
                .find("alarms.toml:3: alarms.movement_debounce_ms"),
            std::string::npos);
  EXPECT_NE(problems_text("[alarms]\nmovement_debounse_ms = 100\n").find("movement_debounse_ms"),
            std::string::npos)
      << "a misspelt key is an error, not a silent default";
}

}  // namespace
}  // namespace fleetgw::config
