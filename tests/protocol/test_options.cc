// Every uncertain reading of spec §6 that issue 11 made configurable changes the decoding when
// set (U6, U7, U11, U14, U17, U18, U20, U22). Raw DATA bytes are hand-written.
#include <gtest/gtest.h>

#include <cmath>

#include "motinova/codec.h"
#include "motinova/fault_names.h"
#include "test_util.h"

namespace motinova {
namespace {

using test::hex;

DecodedMessage decoded(const AppFrame& frame, const DecodeOptions& options) {
  DecodedMessage m;
  decode(frame, Catalogue::standard(), options, m);
  return m;
}

AppFrame report(uint16_t id, uint8_t function, const char* data) {
  const auto bytes = hex(data);
  return make_frame(id, Mode::kReport, function, bytes);
}

// U6: the MC's uncertain bits. Naming another bit's table entry moves its code and severity.
TEST(UncertainOptions, McFaultNames) {
  DecodeOptions options;
  auto def = describe_fault(FaultSource::kMc, 0x0080, options);
  ASSERT_TRUE(def);
  EXPECT_EQ(def->name, "hall_or_brake_fault");
  EXPECT_EQ(def->code, 18);
  options.fault_names.push_back({FaultSource::kMc, 0x0080, "phase_line_fault"});
  options.fault_names.push_back({FaultSource::kMc, 0x0100, "hall_or_brake_fault"});
  options.fault_names.push_back({FaultSource::kMc, 0x00400000, "throttle_comm_fault"});
  def = describe_fault(FaultSource::kMc, 0x0080, options);
  EXPECT_EQ(def->name, "phase_line_fault");
  EXPECT_EQ(def->code, 22);
  EXPECT_EQ(def->severity, Severity::kCritical);
  def = describe_fault(FaultSource::kMc, 0x0100, options);
  EXPECT_EQ(def->code, 18);
  def = describe_fault(FaultSource::kMc, 0x00400000, options);
  EXPECT_EQ(def->name, "throttle_comm_fault");
  EXPECT_EQ(def->code, -1);
  EXPECT_EQ(def->severity, Severity::kWarning);
  // Other sources are untouched.
  EXPECT_EQ(describe_fault(FaultSource::kObc, 0x0080, options)->name, "mos_short_circuit");
}

// U18 (IOT), U20 (locks), U22 (BMS group B).
TEST(UncertainOptions, IotLockAndBmsFaultNames) {
  DecodeOptions options;
  EXPECT_EQ(describe_fault(FaultSource::kIot, 0x0001, options)->name, "lte_module");
  EXPECT_EQ(describe_fault(FaultSource::kLock, 0x0040, options)->name, "motor_stall");
  EXPECT_EQ(describe_fault(FaultSource::kBms, 0x0800, options)->name, "protection_bit_11");
  options.fault_names = {{FaultSource::kIot, 0x0001, "ble_module"},
                         {FaultSource::kIot, 0x0008, "sim_card"},
                         {FaultSource::kLock, 0x0040, "position_switch_fault"},
                         {FaultSource::kBms, 0x0800, "cell_imbalance_protect"}};
  EXPECT_EQ(describe_fault(FaultSource::kIot, 0x0001, options)->name, "ble_module");
  EXPECT_EQ(describe_fault(FaultSource::kIot, 0x0008, options)->name, "sim_card");
  EXPECT_EQ(describe_fault(FaultSource::kLock, 0x0040, options)->name, "position_switch_fault");
  EXPECT_EQ(describe_fault(FaultSource::kBms, 0x0800, options)->name, "cell_imbalance_protect");
  // A decoded lock fault word names its bits through the options.
  const auto m = decoded(report(0x770, 0x11, "00 00 00 40"), options);
  ASSERT_EQ(m.name(), "lock_faults");
  std::vector<std::string> names;
  for_each_active_fault(FaultSource::kLock, static_cast<uint32_t>(*m.raw("raw")), options,
                        [&](uint32_t, const FaultDef* d) { names.emplace_back(d->name); });
  EXPECT_EQ(names, std::vector<std::string>{"position_switch_fault"});
}

TEST(UncertainOptions, FaultBitKeys) {
  EXPECT_EQ(parse_fault_bit("0x0080"), 0x0080u);
  EXPECT_EQ(parse_fault_bit("low_0x0080"), 0x0080u);
  EXPECT_EQ(parse_fault_bit("high_0x0002"), 0x00020000u);
  EXPECT_EQ(parse_fault_bit("0x00020000"), 0x00020000u);
  EXPECT_FALSE(parse_fault_bit("0x0003"));        // two bits
  EXPECT_FALSE(parse_fault_bit("high_0x10000"));  // beyond a 16-bit group
  EXPECT_FALSE(parse_fault_bit("128"));           // hex only
  EXPECT_FALSE(parse_fault_bit("0x"));
}

// U7: assist-level names.
TEST(UncertainOptions, AssistNames) {
  DecodeOptions options;
  const AppFrame f = report(0x761, 0x30, "33 F1");
  EXPECT_EQ(decoded(f, options).text("assist"), "special_33");
  for (auto& a : options.assist_names) {
    if (a.value == 0x33) a.name = "smart";
  }
  EXPECT_EQ(decoded(f, options).text("assist"), "smart");
}

// U11: wheel size and wheel adjust units; decoded always as circumference / adjust in cm.
TEST(UncertainOptions, WheelUnits) {
  const AppFrame f = report(0x713, 0x54, "DC 02 19 FB 00 00 00 00");  // 220, mode 2, 25, -5
  DecodeOptions options;
  EXPECT_DOUBLE_EQ(*decoded(f, options).number("wheel_size_cm"), 220.0);
  EXPECT_DOUBLE_EQ(*decoded(f, options).number("wheel_adjust_cm"), -5.0);
  options.wheel_size_unit = WheelSizeUnit::kDiameterCm;
  options.wheel_adjust_unit = WheelAdjustUnit::kMm;
  EXPECT_NEAR(*decoded(f, options).number("wheel_size_cm"), 220.0 * M_PI, 1e-9);
  EXPECT_DOUBLE_EQ(*decoded(f, options).number("wheel_adjust_cm"), -0.5);
  const AppFrame inch = report(0x713, 0x54, "1B 02 19 00 00 00 00 00");  // 27-inch wheel
  options.wheel_size_unit = WheelSizeUnit::kDiameterInch;
  EXPECT_NEAR(*decoded(inch, options).number("wheel_size_cm"), 27 * 2.54 * M_PI, 1e-9);
}

// U14: answers of the MC on 0x716 or 0x710.
TEST(UncertainOptions, McAnswerId) {
  const char* data = "DC 02 19 FB 00 00 00 00";
  DecodeOptions options;
  EXPECT_EQ(decoded(report(0x713, 0x54, data), options).name(), "mc_settings");
  EXPECT_EQ(decoded(report(0x716, 0x54, data), options).name(), "unknown");
  options.mc_answer_id = McAnswerId::k716;
  const AppFrame on716 = report(0x716, 0x54, data);
  const auto m = decoded(on716, options);
  EXPECT_EQ(m.name(), "mc_settings");
  EXPECT_DOUBLE_EQ(*m.number("speed_limit_kmh"), 25.0);
  EXPECT_EQ(decoded(report(0x710, 0x54, data), options).name(), "unknown");
  options.mc_answer_id = McAnswerId::k710;
  EXPECT_EQ(decoded(report(0x710, 0x55, "01 02 03 04 05 06 00 00 00 00 00 00 00 00 00 00"), options)
                .name(),
            "mc_params2");
  options.mc_answer_id = McAnswerId::kAuto;
  EXPECT_EQ(decoded(report(0x716, 0x54, data), options).name(), "mc_settings");
  EXPECT_EQ(decoded(report(0x710, 0x54, data), options).name(), "mc_settings");
  // The MC's own broadcasts keep their meaning, and its handshake (a read) is no answer.
  EXPECT_EQ(decoded(report(0x710, 0x15, "00 00 30 39 00 00 00 3C 00 00 00 7B 00 00 00 0A"), options)
                .name(),
            "mc_odometer");
  const auto hs = hex("48 41 4E 44 53 48 41 4B 45");
  EXPECT_EQ(decoded(make_frame(0x716, Mode::kRead, 0x50, hs), options).name(), "unknown");
}

// U17: pack statistics currents, time unit and counter order.
TEST(UncertainOptions, PackStatistics) {
  // offset 2: 0x55AA = 21.930 A, offset 4: 0x2710 = 10.000 A, 8: 0x0078 = 120, 10: 0x003C = 60,
  // counters at 12.. = 1, 2, 3, ... 9.
  const AppFrame f = report(0x725, 0x50,
                            "46 14 55 AA 27 10 01 F4 00 78 00 3C 00 01 00 02 00 03 00 04 "
                            "00 05 00 06 00 07 00 08 00 09 00 01 E2 40 5F 00 00 00 00 00");
  DecodeOptions options;
  auto m = decoded(f, options);
  EXPECT_NEAR(*m.number("max_discharge_current_a"), 21.93, 1e-9);
  EXPECT_NEAR(*m.number("max_charge_current_a"), 10.0, 1e-9);
  EXPECT_DOUBLE_EQ(*m.number("charge_time_total_h"), 120);
  EXPECT_DOUBLE_EQ(*m.number("over_charge_count"), 1);
  EXPECT_DOUBLE_EQ(*m.number("discharge_under_temp_count"), 9);

  options.pack_stats_discharge_current_first = false;
  options.pack_stats_time_unit = PackTimeUnit::kMinutes;
  std::reverse(options.pack_stats_counter_order.begin(), options.pack_stats_counter_order.end());
  m = decoded(f, options);
  EXPECT_NEAR(*m.number("max_discharge_current_a"), 10.0, 1e-9);
  EXPECT_NEAR(*m.number("max_charge_current_a"), 21.93, 1e-9);
  EXPECT_DOUBLE_EQ(*m.number("charge_time_total_h"), 2.0);
  EXPECT_DOUBLE_EQ(*m.number("charge_time_longest_h"), 1.0);
  EXPECT_DOUBLE_EQ(*m.number("over_charge_count"), 9);
  EXPECT_DOUBLE_EQ(*m.number("discharge_under_temp_count"), 1);
  EXPECT_DOUBLE_EQ(*m.number("short_circuit_count"), 5);
  EXPECT_DOUBLE_EQ(*m.number("soh_pct"), 95);  // untouched fields stay where they are
}

// The writer places and scales fields with the same options, so a sender and a receiver that
// agree on a reading round-trip.
TEST(UncertainOptions, WriterFollowsTheOptions) {
  DecodeOptions options;
  options.pack_stats_discharge_current_first = false;
  options.pack_stats_time_unit = PackTimeUnit::kMinutes;
  options.wheel_adjust_unit = WheelAdjustUnit::kMm;
  const MessageDesc* stats = Catalogue::standard().find("pack_stats", 0x725);
  ASSERT_NE(stats, nullptr);
  const AppFrame f = MessageWriter(*stats, options)
                         .value("max_discharge_current_a", 3.5)
                         .value("charge_time_total_h", 1.5)
                         .frame();
  EXPECT_EQ(f.data[4], 0x0D);  // 3500 mA at offset 4
  EXPECT_EQ(f.data[5], 0xAC);
  EXPECT_EQ(f.data[9], 90);  // 90 minutes
  EXPECT_NEAR(*decoded(f, options).number("max_discharge_current_a"), 3.5, 1e-9);
  const MessageDesc* settings = Catalogue::standard().find("mc_settings", 0x713);
  const AppFrame s = MessageWriter(*settings, options).value("wheel_adjust_cm", -0.7).frame();
  EXPECT_EQ(static_cast<int8_t>(s.data[3]), -7);
}

}  // namespace
}  // namespace motinova
