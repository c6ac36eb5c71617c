// The [protocol] options of issue 11 (U6, U7, U11, U14, U17, U18, U20, U22) read from a config
// file: the shipped file decodes like the built-in defaults, each key changes decoding, and bad
// values are refused with file:line:key.
#include <gtest/gtest.h>

#include <string>

#include "gateway/config/config.h"
#include "motinova/codec.h"
#include "motinova/fault_names.h"

namespace fleetgw::config {
namespace {

using motinova::FaultSource;

motinova::DecodeOptions protocol_of(const std::string& toml) {
  return parse_config(toml, "test.toml").protocol;
}

std::string problem_of(const std::string& toml) {
  try {
    parse_config(toml, "test.toml");
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string decoded_name(const motinova::DecodeOptions& p, uint16_t id, uint8_t function,
                         std::vector<uint8_t> data, std::string_view field = {}) {
  const auto frame = motinova::make_frame(id, motinova::Mode::kReport, function, data);
  motinova::DecodedMessage m;
  motinova::decode(frame, motinova::Catalogue::standard(), p, m);
  if (field.empty()) return std::string(m.name());
  return std::string(m.text(field));
}

TEST(ProtocolConfig, ShippedFileDecodesLikeTheDefaults) {
  const auto file = load_config(FLEETGW_DEFAULT_CONFIG).protocol;
  const motinova::DecodeOptions defaults;
  for (auto source : {FaultSource::kMc, FaultSource::kBms, FaultSource::kIot, FaultSource::kLock}) {
    for (int bit = 0; bit < 32; ++bit) {
      const auto a = motinova::describe_fault(source, 1u << bit, file);
      const auto b = motinova::describe_fault(source, 1u << bit, defaults);
      ASSERT_EQ(a.has_value(), b.has_value()) << bit;
      if (!a) continue;
      EXPECT_EQ(a->name, b->name) << motinova::fault_source_name(source) << " bit " << bit;
      EXPECT_EQ(a->code, b->code);
      EXPECT_EQ(a->severity, b->severity);
    }
  }
  EXPECT_GE(file.fault_names.size(), 20u);  // the file really lists the uncertain bits
  ASSERT_EQ(file.assist_names.size(), defaults.assist_names.size());
  for (std::size_t i = 0; i < defaults.assist_names.size(); ++i) {
    EXPECT_EQ(file.assist_names[i].name, defaults.assist_names[i].name);
  }
  EXPECT_EQ(file.mc_answer_id, defaults.mc_answer_id);
  EXPECT_EQ(file.wheel_size_unit, defaults.wheel_size_unit);
  EXPECT_EQ(file.wheel_adjust_unit, defaults.wheel_adjust_unit);
  EXPECT_EQ(file.pack_stats_discharge_current_first, defaults.pack_stats_discharge_current_first);
  EXPECT_EQ(file.pack_stats_time_unit, defaults.pack_stats_time_unit);
  EXPECT_EQ(file.pack_stats_counter_order, defaults.pack_stats_counter_order);
}

TEST(ProtocolConfig, EachKeyChangesDecoding) {
  const auto p = protocol_of(R"(
[protocol]
mc_answer_id = "auto"
wheel_size_unit = "diameter_inch"
wheel_adjust_unit = "mm"
pack_stats_currents = "charge_first"
pack_stats_time_unit = "min"
[protocol.assist_names]
0x33 = "smart"
[protocol.mc_fault_names]
high_0x0020 = "te_mc_comm_fault"
[protocol.bms_fault_names]
low_0x0800 = "cell_imbalance_protect"
[protocol.iot_fault_names]
low_0x0001 = "ble_module"
[protocol.lock_fault_names]
low_0x0040 = "bolt_jammed"
)");
  EXPECT_EQ(p.mc_answer_id, motinova::McAnswerId::kAuto);
  EXPECT_EQ(decoded_name(p, 0x716, 0x54, {0x1B, 2, 25, 0, 0, 0, 0, 0}), "mc_settings");
  EXPECT_EQ(p.wheel_size_unit, motinova::WheelSizeUnit::kDiameterInch);
  EXPECT_EQ(p.wheel_adjust_unit, motinova::WheelAdjustUnit::kMm);
  EXPECT_FALSE(p.pack_stats_discharge_current_first);
  EXPECT_EQ(p.pack_stats_time_unit, motinova::PackTimeUnit::kMinutes);
  EXPECT_EQ(decoded_name(p, 0x761, 0x30, {0x33, 0xF1}, "assist"), "smart");
  EXPECT_EQ(decoded_name(p, 0x761, 0x30, {0x02, 0xF1}, "assist"), "norm");  // merged
  EXPECT_EQ(motinova::describe_fault(FaultSource::kMc, 0x00200000, p)->name, "te_mc_comm_fault");
  EXPECT_EQ(motinova::describe_fault(FaultSource::kBms, 0x0800, p)->name, "cell_imbalance_protect");
  EXPECT_EQ(motinova::describe_fault(FaultSource::kIot, 0x0001, p)->name, "ble_module");
  EXPECT_EQ(motinova::describe_fault(FaultSource::kLock, 0x0040, p)->name, "bolt_jammed");

  const auto order = protocol_of(R"(
[protocol]
pack_stats_counter_order = ["short_circuit_count", "over_discharge_count", "charge_over_current_count", "discharge_over_current_count", "over_charge_count", "charge_over_temp_count", "charge_under_temp_count", "discharge_over_temp_count", "discharge_under_temp_count"]
)");
  EXPECT_EQ(order.pack_stats_counter_order[0], "short_circuit_count");
  EXPECT_EQ(order.pack_stats_counter_order[4], "over_charge_count");
}

TEST(ProtocolConfig, BadValuesNameFileLineAndKey) {
  auto expect_problem = [](const std::string& toml, const std::string& needle) {
    const std::string what = problem_of(toml);
    EXPECT_NE(what.find(needle), std::string::npos) << "got: " << what;
  };
  expect_problem("[protocol]\nmc_answer_id = \"0x714\"\n", "test.toml:2: protocol.mc_answer_id");
  expect_problem("[protocol]\nwheel_size_unit = \"mm\"\n", "protocol.wheel_size_unit");
  expect_problem("[protocol.mc_fault_names]\nlow_0x0003 = \"x\"\n",
                 "test.toml:2: protocol.mc_fault_names.low_0x0003");
  expect_problem("[protocol.lock_fault_names]\nlow_0x0008 = \"Bad Name\\n\"\n",
                 "protocol.lock_fault_names.low_0x0008");
  expect_problem("[protocol.assist_names]\n0x100 = \"x\"\n", "protocol.assist_names.0x100");
  expect_problem(
      "[protocol]\npack_stats_counter_order = [\"a\", \"b\", \"c\", \"d\", \"e\", \"f\", \"g\", "
      "\"h\", \"i\"]\n",
      "protocol.pack_stats_counter_order");
  expect_problem("[protocol.mc_fault_names]\nlow_0x0080 = 5\n", "expected a string");
}

}  // namespace
}  // namespace fleetgw::config
