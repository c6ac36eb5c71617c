// The configuration loader: defaults, the shipped file, and every kind of mistake reported with
// file, line and key.
#include <gtest/gtest.h>

#include "gateway/config/config.h"

namespace fleetgw::config {
namespace {

std::vector<std::string> problems_of(const std::string& text) {
  try {
    parse_config(text, "test.toml");
  } catch (const ConfigError& e) {
    return e.problems;
  }
  return {};
}

TEST(Config, EmptyFileIsTheDefaults) {
  const Config c = parse_config("", "empty.toml");
  EXPECT_EQ(c.can.transport, "socketcan");
  EXPECT_EQ(c.protocol.crc_order, motinova::CrcOrder::kBig);
  EXPECT_EQ(c.protocol.data_order, motinova::ByteOrder::kBig);
  EXPECT_EQ(c.node.request_retry_ms, 200);
  EXPECT_EQ(c.node.request_timeout_ms, 1000);
  EXPECT_TRUE(c.mqtt.verify_server);
}

TEST(Config, ShippedDefaultFileLoadsAndMatchesTheDefaults) {
  const Config file = load_config(FLEETGW_DEFAULT_CONFIG);
  const Config defaults = parse_config("", "empty.toml");
  EXPECT_EQ(file.vehicle.id, defaults.vehicle.id);
  EXPECT_EQ(file.can.reassembly_gap_ms, defaults.can.reassembly_gap_ms);
  EXPECT_EQ(file.protocol.lock_kinds, defaults.protocol.lock_kinds);
  EXPECT_EQ(file.protocol.lock_state_names, defaults.protocol.lock_state_names);
  EXPECT_EQ(file.node.bms_poll_ms, defaults.node.bms_poll_ms);
  EXPECT_EQ(file.storage.max_mb, defaults.storage.max_mb);
  EXPECT_EQ(file.mqtt.keepalive_s, defaults.mqtt.keepalive_s);
  EXPECT_EQ(file.mqtt.tcp_nodelay, defaults.mqtt.tcp_nodelay);
  EXPECT_EQ(file.mqtt.qos, defaults.mqtt.qos);
  EXPECT_EQ(file.mqtt.telemetry_qos, defaults.mqtt.telemetry_qos);
  EXPECT_EQ(file.mqtt.live_telemetry_max_age_ms, defaults.mqtt.live_telemetry_max_age_ms);
  EXPECT_EQ(file.mqtt.status_interval_ms, defaults.mqtt.status_interval_ms);
  EXPECT_EQ(file.mqtt.batch_max_samples, defaults.mqtt.batch_max_samples);
  EXPECT_EQ(file.mqtt.batch_max_ms, defaults.mqtt.batch_max_ms);
  EXPECT_EQ(file.mqtt.reconnect_max_ms, defaults.mqtt.reconnect_max_ms);
}

TEST(Config, UnknownKeyNamesFileLineAndKey) {
  const auto p = problems_of("[can]\ntransport = \"sim\"\nbitrate = 250000\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0], "test.toml:3: can.bitrate: unknown key");
}

TEST(Config, UnknownSectionIsReported) {
  const auto p = problems_of("[cann]\ntransport = \"sim\"\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NE(p[0].find("cann: unknown key"), std::string::npos) << p[0];
}

TEST(Config, WrongTypeIsReported) {
  const auto p = problems_of("[node]\noffline_timeout_ms = \"3s\"\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0], "test.toml:2: node.offline_timeout_ms: expected an integer");
}

TEST(Config, OutOfRangeIsReported) {
  const auto p = problems_of("[storage]\nmax_mb = 0\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0], "test.toml:2: storage.max_mb: 0 is out of range [1, 1000000]");
}

TEST(Config, BadChoiceListsTheAllowedValues) {
  const auto p = problems_of("[protocol]\ncrc_order = \"big\"\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NE(p[0].find("expected one of be, le, auto, got \"big\""), std::string::npos) << p[0];
}

TEST(Config, EveryProblemIsReportedAtOnce) {
  const auto p = problems_of(
      "[can]\ntransport = \"cam\"\n[mqtt]\nkeepalive_s = 1\ncert_file = \"c.pem\"\n[ride]\nfoo = "
      "1\n");
  EXPECT_EQ(p.size(), 4u);
}

TEST(Config, SyntaxErrorHasLineAndColumn) {
  const auto p = problems_of("[can]\ntransport = \n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0].rfind("test.toml:2:", 0), 0u) << p[0];
}

TEST(Config, ProtocolOptionsAreApplied) {
  const Config c = parse_config(
      "[protocol]\ncrc_order = \"auto\"\ndata_order = \"le\"\nmc_fault_layout = \"swapped\"\n"
      "bms_current_charge_positive = false\nlock_kinds = [\"battery\", \"\", \"\", \"\", "
      "\"frame\"]\n",
      "p.toml");
  EXPECT_EQ(c.protocol.crc_order, motinova::CrcOrder::kAuto);
  EXPECT_EQ(c.protocol.data_order, motinova::ByteOrder::kLittle);
  EXPECT_EQ(c.protocol.mc_fault_layout, motinova::FaultWordLayout::kSwappedGroups);
  EXPECT_FALSE(c.protocol.bms_current_charge_positive);
  EXPECT_EQ(c.protocol.lock_kinds[0], "battery");
  EXPECT_EQ(c.protocol.lock_kinds[1], "");
}

TEST(Config, LockStateNamesMustBeSevenNonEmptyStrings) {
  EXPECT_EQ(problems_of("[protocol]\nlock_state_names = [\"a\", \"b\"]\n").size(), 1u);
  EXPECT_EQ(
      problems_of("[protocol]\nlock_state_names = [\"a\",\"b\",\"c\",\"d\",\"e\",\"f\",\"\"]\n")
          .size(),
      1u);
}

TEST(Config, IdentityMustFitTheModelInfoBlock) {
  const auto p = problems_of("[node]\nmodel = \"THIS-MODEL-NAME-IS-TOO-LONG\"\n");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NE(p[0].find("node.model"), std::string::npos);
}

TEST(Config, MissingFileIsReported) {
  try {
    load_config("/nonexistent/fleetgw.toml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/fleetgw.toml"), std::string::npos);
  }
}

}  // namespace
}  // namespace fleetgw::config
