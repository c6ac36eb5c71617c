// GatewayConfig (tests/support/gateway_config.h) writes what the gateway's own loader reads:
// every key a builder call sets arrives in config::Config, a path with quotes, backslashes and
// a tab stays one string, and setting a key again replaces it (TOML refuses a key given twice,
// so a builder that appended instead would fail here).
#include "tests/support/gateway_config.h"

#include <gtest/gtest.h>

#include <string>

#include "gateway/config/config.h"
#include "tests/support/temp_dir.h"

namespace {

using fleetgw::testing::GatewayConfig;
using fleetgw::testing::TempDir;

// 32 zero bytes in base64: a well-formed Ed25519 public key for the loader.
constexpr const char* kKeyLine = R"(ops = "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA=")";

TEST(GatewayConfigBuilder, TheGatewaysLoaderReadsEveryKeyTheBuilderSets) {
  TempDir dir;
  const auto store = dir / "a \"quoted\" \\ dir\twith tab.db";
  GatewayConfig c("bike-7", store);
  c.sim(dir / "scenario.toml", 1).sim(dir / "ride.toml", 20).set("sim", "start_now", "false");
  c.gnss(2948).set("gnss", "max_age_ms", "2500");
  c.mqtt("tcp://127.0.0.1:1883").geofence(dir / "zones.pb", kKeyLine);
  const auto file = c.write(dir / "fleetgw.toml");

  const auto cfg = fleetgw::config::load_config(file);
  EXPECT_EQ(cfg.vehicle.id, "bike-7");
  EXPECT_EQ(cfg.can.transport, "sim");
  EXPECT_EQ(cfg.storage.path, store.string());
  EXPECT_EQ(cfg.status.socket, "");
  EXPECT_EQ(cfg.sim.scenario, (dir / "ride.toml").string());
  EXPECT_EQ(cfg.sim.speed, 20.0);
  EXPECT_TRUE(cfg.sim.lockstep);
  EXPECT_FALSE(cfg.sim.start_now);
  EXPECT_TRUE(cfg.gnss.enabled);
  EXPECT_EQ(cfg.gnss.gpsd, "127.0.0.1:2948");
  EXPECT_EQ(cfg.gnss.max_age_ms, 2500);
  EXPECT_EQ(cfg.gnss.reconnect_max_ms, 1000);
  EXPECT_TRUE(cfg.mqtt.enabled);
  EXPECT_EQ(cfg.mqtt.uri, "tcp://127.0.0.1:1883");
  EXPECT_TRUE(cfg.geofence.enabled);
  EXPECT_EQ(cfg.geofence.bundle_file, (dir / "zones.pb").string());
  EXPECT_EQ(cfg.command.trusted_keys.count("ops"), 1u) << c.text();
}

TEST(GatewayConfigBuilder, ControlCharactersAreEscapedNotWrittenRaw) {
  EXPECT_EQ(fleetgw::testing::toml_string("a\"b\\c\nd\x7f"), R"("a\"b\\c\u000Ad\u007F")");
}

}  // namespace
