// The campaign language: a file in TOML or JSON, the gateway's rules (each refusal names its
// field) and the cost bound every accepted campaign carries.
#include <gtest/gtest.h>

#include <functional>

#include "campaign_test_util.h"
#include "gateway/campaign/campaign_file.h"

namespace fleetgw::campaign {
namespace {

std::string refusal(const std::function<void(v1::Campaign&)>& change) {
  auto c = test::base_campaign();
  change(c);
  auto r = compile_campaign(c);
  if (std::holds_alternative<CompiledCampaign>(r)) return "accepted";
  return std::get<std::string>(r);
}

TEST(CampaignSpec, TheBaseCampaignIsAcceptedWithItsCost) {
  const auto c = test::compiled(test::base_campaign());
  EXPECT_EQ(c.cost.max_samples_per_hour, 3600u);
  EXPECT_EQ(c.cost.max_bytes_per_hour, 3600u * sample_bytes_bound(*c.signals[0]));
  EXPECT_EQ(c.cost.disk_budget_bytes, 1u << 20);
}

TEST(CampaignSpec, RefusalsNameTheField) {
  EXPECT_EQ(refusal([](auto& c) { c.set_id("a b"); }).rfind("id:", 0), 0u);
  EXPECT_EQ(refusal([](auto& c) { c.set_version(0); }), "version: must be at least 1");
  EXPECT_EQ(refusal([](auto& c) { c.add_signals("bms.cells.cells_mv[16]"); }),
            "signals[1]: unknown signal 'bms.cells.cells_mv[16]' (fleetgw signals lists them)");
  EXPECT_EQ(refusal([](auto& c) { c.add_signals("mc.status.motor_temp_c"); }),
            "signals[1]: mc.status.motor_temp_c repeated");
  EXPECT_EQ(refusal([](auto& c) { c.clear_signals(); }).rfind("signals: none", 0), 0u);
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_sampling()->set_period_ms(0);
            }).rfind("sampling.period_ms: 0 is outside 10..", 0),
            0u);
  EXPECT_EQ(
      refusal([](auto& c) { c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_WINDOW); }),
      "sampling.kind: window sampling needs a condition trigger (its event)");
  EXPECT_EQ(refusal([](auto& c) { c.set_disk_budget_bytes(0); }).rfind("disk_budget_bytes:", 0),
            0u);
  EXPECT_EQ(refusal([](auto& c) { c.set_end_us(c.start_us()); }).rfind("end_us:", 0), 0u);
  EXPECT_EQ(refusal([](auto& c) { c.set_end_us(c.start_us() + 91ll * 86'400'000'000); }),
            "end_us: more than 90 days after start_us");
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_target()->set_all_vehicles(false);
            }).rfind("target: no scope", 0),
            0u);
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_target()->add_firmware()->set_node("moon");
            }).rfind("target.firmware[0].node:", 0),
            0u);
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
              c.mutable_trigger()->mutable_condition()->set_kind(v1::CAMPAIGN_CONDITION_KIND_ABOVE);
              c.mutable_trigger()->mutable_condition()->set_signal("mc.device_info.fw");
            }),
            "trigger.condition.signal: mc.device_info.fw is text, not numeric");
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
              auto* k = c.mutable_trigger()->mutable_condition();
              k->set_kind(v1::CAMPAIGN_CONDITION_KIND_RISING_EDGE);
              k->set_signal("mc.status.motor_temp_c");
            }),
            "sampling.kind: an edge or fault condition is an instant: it needs window sampling");
  EXPECT_EQ(refusal([](auto& c) {
              c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
              auto* k = c.mutable_trigger()->mutable_condition();
              k->set_kind(v1::CAMPAIGN_CONDITION_KIND_FAULT_ACTIVE);
              k->set_signal("mc.status.motor_temp_c");
            }).rfind("trigger.condition.signal: mc.status.motor_temp_c is not a fault", 0),
            0u);
}

TEST(CampaignSpec, AnUnboundedRingIsRefused) {
  auto c = test::base_campaign();
  c.clear_signals();
  for (int i = 0; i < 16; ++i) c.add_signals("bms.cells.cells_mv[" + std::to_string(i) + "]");
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_CONDITION);
  c.mutable_trigger()->mutable_condition()->set_kind(v1::CAMPAIGN_CONDITION_KIND_ABOVE);
  c.mutable_trigger()->mutable_condition()->set_signal("bms.status.temp_c");
  c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_WINDOW);
  c.mutable_sampling()->set_period_ms(10);
  c.mutable_sampling()->set_before_ms(600'000);  // 60,001 x 16 samples
  auto r = compile_campaign(c);
  ASSERT_TRUE(std::holds_alternative<std::string>(r));
  EXPECT_EQ(std::get<std::string>(r).rfind("sampling.before_ms: the ring would hold 960016", 0),
            0u);
  c.mutable_sampling()->set_before_ms(30'000);
  EXPECT_EQ(test::compiled(c).cost.ring_samples, 16u * 3001u);
}

constexpr const char* kToml = R"(
id = "hot-pack"
version = 3
description = "cells while the pack is hot"
signals = ["bms.cells.cells_mv[0]", "bms.status.temp_c"]
priority = 2
disk_budget_bytes = 1048576
start = 2026-12-01T00:00:00Z
end = 2026-12-15T00:00:00Z

[trigger]
kind = "condition"
condition = { kind = "above", signal = "bms.status.temp_c", threshold = 45, hysteresis = 2 }

[sampling]
kind = "every"
period_ms = 1000

[target]
groups = ["berlin-north"]
firmware = [{ node = "bms", prefix = "BMS-2." }]
)";

TEST(CampaignFile, TomlAndJsonGiveTheSameCampaign) {
  auto toml = parse_campaign_text(kToml, "hot.toml");
  ASSERT_TRUE(std::holds_alternative<v1::Campaign>(toml)) << std::get<std::string>(toml);
  const auto& c = std::get<v1::Campaign>(toml);
  EXPECT_EQ(c.id(), "hot-pack");
  EXPECT_EQ(c.version(), 3u);
  EXPECT_EQ(c.start_us(), 1'796'083'200'000'000);
  EXPECT_EQ(c.trigger().condition().threshold_e6(), 45'000'000);
  EXPECT_EQ(c.trigger().condition().hysteresis_e6(), 2'000'000u);
  EXPECT_EQ(c.target().firmware(0).prefix(), "BMS-2.");
  const char* json =
      R"({"id": "hot-pack", "version": 3, "description": "cells while the pack is hot",
    "signals": ["bms.cells.cells_mv[0]", "bms.status.temp_c"], "priority": 2,
    "disk_budget_bytes": 1048576, "start": "2026-12-01T00:00:00Z", "end": "2026-12-15T00:00:00Z",
    "trigger": {"kind": "condition", "condition": {"kind": "above", "signal": "bms.status.temp_c",
      "threshold": 45, "hysteresis": 2}},
    "sampling": {"kind": "every", "period_ms": 1000},
    "target": {"groups": ["berlin-north"], "firmware": [{"node": "bms", "prefix": "BMS-2."}]}})";
  auto from_json = parse_campaign_text(json, "hot.json");
  ASSERT_TRUE(std::holds_alternative<v1::Campaign>(from_json)) << std::get<std::string>(from_json);
  EXPECT_EQ(std::get<v1::Campaign>(from_json).SerializeAsString(), c.SerializeAsString());
}

TEST(CampaignFile, MalformedFilesAreRefusedNamingTheKey) {
  auto bad = [](std::string text) {
    auto r = parse_campaign_text(text, "c.toml");
    return std::holds_alternative<std::string>(r) ? std::get<std::string>(r) : "parsed";
  };
  std::string t = kToml;
  EXPECT_EQ(bad(t + "colour = \"red\"\n"), "c.toml: target.colour: unknown key 'colour'");
  std::string typo = t;
  typo.replace(typo.find("period_ms = 1000"), 16, "period_ms = \"1s\"");
  EXPECT_EQ(bad(typo), "c.toml: sampling.period_ms: must be a non-negative integer");
  std::string kind = t;
  kind.replace(kind.find("kind = \"every\""), 14, "kind = \"often\"");
  EXPECT_EQ(bad(kind), "c.toml: sampling.kind: 'often' is not one of every, on_change, window");
  EXPECT_EQ(bad("id = ").rfind("c.toml:1:", 0), 0u);
}

TEST(CampaignFile, AZoneTriggerNamesItsZone) {
  std::string t = kToml;
  const auto from = t.find("kind = \"condition\"");
  const auto to = t.find("[sampling]");
  t.replace(from, to - from, "kind = \"zone\"\nzone = \"depot-north\"\n\n");
  auto r = parse_campaign_text(t, "zone.toml");
  ASSERT_TRUE(std::holds_alternative<v1::Campaign>(r)) << std::get<std::string>(r);
  auto c = std::get<v1::Campaign>(r);
  c.set_issued_at_us(c.start_us());  // what `campaign sign` sets
  EXPECT_EQ(c.trigger().kind(), v1::CAMPAIGN_TRIGGER_KIND_ZONE);
  EXPECT_EQ(c.trigger().zone(), "depot-north");
  auto compiled = compile_campaign(c);
  ASSERT_TRUE(std::holds_alternative<CompiledCampaign>(compiled))
      << std::get<std::string>(compiled);
  EXPECT_EQ(trigger_name(std::get<CompiledCampaign>(compiled).trigger), "zone");
}

}  // namespace
}  // namespace fleetgw::campaign
