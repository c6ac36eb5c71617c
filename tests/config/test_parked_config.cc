// The [parked] section and [mqtt] state_interval_ms (issue 13): the shipped file spells out the
// defaults, values are read, and a stale-rule poll period that would make a polled node look
// silent is refused naming the key.
#include <gtest/gtest.h>

#include <string>

#include "gateway/config/config.h"

namespace fleetgw::config {
namespace {

std::string parked_problems(const std::string& text) {
  try {
    parse_config(text, "parked.toml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return {};
}

TEST(ParkedConfig, ShippedFileMatchesTheDefaults) {
  const Config file = load_config(FLEETGW_DEFAULT_CONFIG);
  const Config defaults = parse_config("", "empty.toml");
  EXPECT_EQ(file.parked.enabled, defaults.parked.enabled);
  EXPECT_EQ(file.parked.settle_s, defaults.parked.settle_s);
  EXPECT_EQ(file.parked.poll_interval_ms, defaults.parked.poll_interval_ms);
  EXPECT_EQ(file.parked.telemetry_batch_ms, defaults.parked.telemetry_batch_ms);
  EXPECT_EQ(file.parked.stale_poll_ms, defaults.parked.stale_poll_ms);
  EXPECT_EQ(file.mqtt.state_interval_ms, defaults.mqtt.state_interval_ms);
  EXPECT_EQ(defaults.mqtt.state_interval_ms, 5000);
  EXPECT_TRUE(defaults.parked.enabled);
}

TEST(ParkedConfig, ValuesAreRead) {
  const Config c = parse_config(
      "[parked]\nenabled = false\nsettle_s = 12\npoll_interval_ms = 60000\n"
      "telemetry_batch_ms = 0\nstale_poll_ms = 1500\n[mqtt]\nstate_interval_ms = 0\n",
      "p.toml");
  EXPECT_FALSE(c.parked.enabled);
  EXPECT_EQ(c.parked.settle_s, 12);
  EXPECT_EQ(c.parked.poll_interval_ms, 60000);
  EXPECT_EQ(c.parked.telemetry_batch_ms, 0);
  EXPECT_EQ(c.parked.stale_poll_ms, 1500);
  EXPECT_EQ(c.mqtt.state_interval_ms, 0);
}

TEST(ParkedConfig, StalePollAtOrAboveTheFaultStaleTimeoutIsRefused) {
  const std::string p = parked_problems("[parked]\nstale_poll_ms = 2000\n");
  EXPECT_NE(p.find("parked.stale_poll_ms"), std::string::npos) << p;
  EXPECT_NE(p.find("node.fault_stale_ms"), std::string::npos) << p;
  EXPECT_EQ(parked_problems("[node]\nfault_stale_ms = 5000\noffline_timeout_ms = 5000\n"
                            "[parked]\nstale_poll_ms = 4000\n"),
            "");
  EXPECT_NE(parked_problems("[parked]\nsettle_s = 0\n").find("parked.settle_s"), std::string::npos);
  EXPECT_NE(parked_problems("[mqtt]\nstate_interval_ms = -1\n").find("mqtt.state_interval_ms"),
            std::string::npos);
}

}  // namespace
}  // namespace fleetgw::config
