// Hand-written raw-bytes vectors (issue 11 item 11): DATA bytes written from the layouts of the
// spec text with the expected physical values worked out by hand, decoded by the catalogue.
// Nothing here is produced by the catalogue's own encoder, so a wrong scale, offset, bias or sign
// in a catalogue table fails a test instead of round-tripping silently. A catalogue-wide check
// makes sure every field with a scale or a bias appears in at least one vector.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <utility>
#include <vector>

#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "test_util.h"

namespace motinova {
namespace {

using test::can_frame;
using test::hex;
using test::RecordingSink;

struct Expect {
  const char* field;
  double value;
};

struct RawVector {
  const char* what;
  uint16_t can_id;
  uint8_t function;
  const char* data;  // DATA bytes as on the wire (big-endian fields, U2 best guess)
  std::vector<Expect> expect;
};

// Each comment shows the hand computation from the spec's encoding.
const std::vector<RawVector>& vectors() {
  static const std::vector<RawVector> v = {
      // §3.3.1: C350 = 50000 mV; 55AA = +21930 mA (s16, charge +); 0C10 = 3088 mAh;
      // 100E = 4110 mAh; 41 = 65 - 40 = 25 °C; 4B = 75 %; 01 charging; 62 = 98 %; 0141 = 321;
      // 002A = 42 min. The bytes of issue 11's reproducer.
      {"bms_status charging",
       0x720,
       0x10,
       "C3 50 55 AA 0C 10 10 0E 41 4B 01 62 01 41 00 2A",
       {{"voltage_v", 50.0},
        {"current_a", 21.93},
        {"remaining_mah", 3088},
        {"full_mah", 4110},
        {"temp_c", 25},
        {"soc_pct", 75},
        {"charging", 1},
        {"soh_pct", 98},
        {"cycles", 321},
        {"charge_time_min", 42}}},
      // 9C40 = 40000 mV; EC78 = -5000 mA (two's complement); 00 = -40 °C; FF = 255 - 40 = 215 °C
      // would be out of range, so the hot end is tested in the next vector.
      {"bms_status discharging, coldest",
       0x720,
       0x10,
       "9C 40 EC 78 00 00 00 00 00 14 00 64 00 00 00 00",
       {{"voltage_v", 40.0}, {"current_a", -5.0}, {"temp_c", -40}, {"soc_pct", 20}}},
      // 8000 = -32768 mA, the most negative s16; 7FFF = +32767 mA; 7D = 125 - 40 = 85 °C.
      {"bms_status current extremes",
       0x720,
       0x10,
       "00 00 80 00 00 00 00 00 7D 00 00 00 00 00 00 00",
       {{"current_a", -32.768}, {"temp_c", 85}}},
      // §3.3.7: 5A = 90 - 40 = 50 °C; 28 = 40 - 40 = 0 °C.
      {"bms_temps",
       0x720,
       0x18,
       "5A 28 00 00 00 00 00 00 00 00 00 00 00 00 00 00",
       {{"temp_max_c", 50}, {"temp_min_c", 0}}},
      // §3.3.10: 46 = 30 °C; 14 = -20 °C; 55AA = 21930 mA; 2710 = 10000 mA; 01F4 = 500 cycles;
      // 30: 0001E240 = 123456 min; 34: 5F = 95 %.
      {"pack_stats",
       0x725,
       0x50,
       "46 14 55 AA 27 10 01 F4 00 00 00 00 00 00 00 00 00 00 00 00 "
       "00 00 00 00 00 00 00 00 00 00 00 01 E2 40 5F 00 00 00 00 00",
       {{"max_temp_c", 30},
        {"min_temp_c", -20},
        {"max_discharge_current_a", 21.93},
        {"max_charge_current_a", 10.0},
        {"cycles", 500},
        {"runtime_min", 123456},
        {"soh_pct", 95}}},
      // §2.5 decoder vector / §3.2.1: 00FD = 25.3 km/h; 0BB8 = 3000 rpm; 00FA = 250 W;
      // BB80 = 48.000 V; 1450 = 5.200 A; 0C = 0.12 Ah/km; 4B/55/50 = 35/45/40 °C; 007B = 12.3 km.
      {"mc_status",
       0x710,
       0x10,
       "00 FD 0B B8 00 FA BB 80 14 50 46 1E 00 02 F1 50 00 41 04 D2 0C 4B 55 50 00 7B 07 08 "
       "00 00 00 00",
       {{"speed_kmh", 25.3},
        {"motor_rpm", 3000},
        {"power_w", 250},
        {"voltage_v", 48.0},
        {"current_a", 5.2},
        {"consumption_ah_per_km", 0.12},
        {"pcb_temp_c", 35},
        {"motor_temp_c", 45},
        {"mcu_temp_c", 40},
        {"trip_km", 12.3},
        {"trip_time_s", 1800}}},
      // §3.2.5: 00003039 = 12345 -> 1234.5 km; 0000007B = 123 -> 12.3 km.
      {"mc_odometer",
       0x710,
       0x15,
       "00 00 30 39 00 00 00 3C 00 00 00 7B 00 00 00 0A",
       {{"odo_km", 1234.5}, {"trip_km", 12.3}}},
      // §3.2.11: offsets 34/35 = 64/1E -> 60/-10 °C; 40..43 = 78/28/5A/32 -> 80/0/50/10 °C.
      {"mc_lifetime_1",
       0x715,
       0xA2,
       "00 00 00 01 00 00 00 02 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 "
       "00 00 00 00 00 00 00 00 00 00 64 1E 00 00 00 00 78 28 5A 32 00 00 00 00",
       {{"pcb_temp_max_c", 60},
        {"pcb_temp_min_c", -10},
        {"motor_temp_max_c", 80},
        {"motor_temp_min_c", 0},
        {"mcu_temp_max_c", 50},
        {"mcu_temp_min_c", 10}}},
      // §2.5 lock vector / §3.6.1: 2EE0 = 12.000 V; 0096 = 0.150 A; 41 = 25 °C; state 2.
      {"lock_status LOCK 1",
       0x770,
       0x10,
       "2E E0 00 96 41 02 00 01 00 00 00 00 00 00 00 00",
       {{"voltage_v", 12.0}, {"current_a", 0.15}, {"temp_c", 25}}},
      // 0x7A0 layout: 36B0 = 14.000 V; 03E8 = 1.000 A; 14 = -20 °C; bytes 8-9 0BB8 = 3000 rpm.
      {"lock_status LOCK 4",
       0x7A0,
       0x10,
       "36 B0 03 E8 14 01 00 00 0B B8 00 00 00 00 00 00",
       {{"voltage_v", 14.0}, {"current_a", 1.0}, {"temp_c", -20}, {"motor_rpm", 3000}}},
      // §5.1 V3.0 angles, s16 0.1°: 0384 = 90.0; FC7C = -900 -> -90.0; 0708 = 180.0;
      // F8F8 = -1800 -> -180.0.
      {"mc_angles",
       0x710,
       0x16,
       "03 84 FC 7C 07 08 F8 F8",
       {{"angle_1_deg", 90.0},
        {"angle_2_deg", -90.0},
        {"angle_3_deg", 180.0},
        {"angle_4_deg", -180.0}}},
      // §5.2 0xAD20: 000F = 1.5°; FFF1 = -15 -> -1.5°.
      {"mc_angle_calibration",
       0x715,
       0xAD,
       "00 0F FF F1 55 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 "
       "00 00 00 00",
       {{"angle_1_deg", 1.5}, {"angle_2_deg", -1.5}}},
  };
  return v;
}

AppFrame frame_of(const RawVector& v) {
  const auto data = hex(v.data);
  return make_frame(v.can_id, Mode::kReport, v.function, data);
}

TEST(RawVectors, EachDecodesToTheHandComputedValues) {
  const DecodeOptions options;
  for (const auto& v : vectors()) {
    const AppFrame frame = frame_of(v);
    DecodedMessage m;
    decode(frame, Catalogue::standard(), options, m);
    ASSERT_EQ(m.status, DecodeStatus::kOk) << v.what;
    for (const auto& e : v.expect) {
      const auto got = m.number(e.field);
      ASSERT_TRUE(got.has_value()) << v.what << ": " << e.field;
      EXPECT_NEAR(*got, e.value, 1e-9) << v.what << ": " << e.field;
    }
  }
}

// The BMS status of issue 11 exactly as the bus carried it (CRC from an independent encoder of
// the spec), through the reassembler and the decoder.
TEST(RawVectors, BmsStatusFromTheWire) {
  Reassembler r;
  RecordingSink sink;
  Micros t{0};
  for (const char* seg : {"55 AA 0C 12 10 10 C3 50", "55 AA 0C 10 10 0E 41 4B",
                          "01 62 01 41 00 2A 0A 49", "AB 2C F0"}) {
    r.push(can_frame(0x720, seg), t += Micros(1000), sink);
  }
  ASSERT_EQ(sink.frames.size(), 1u);
  DecodedMessage m;
  const DecodeOptions options;
  decode(sink.frames[0], Catalogue::standard(), options, m);
  EXPECT_EQ(m.name(), "bms_status");
  EXPECT_NEAR(*m.number("current_a"), 21.93, 1e-9);
  EXPECT_NEAR(*m.number("voltage_v"), 50.0, 1e-9);
  EXPECT_NEAR(*m.number("temp_c"), 25.0, 1e-9);
}

// U4 with the hand-written bytes: discharge-positive flips only the sign.
TEST(RawVectors, BmsCurrentSignOption) {
  DecodeOptions options;
  options.bms_current_charge_positive = false;
  const AppFrame frame = frame_of(vectors()[0]);
  DecodedMessage m;
  decode(frame, Catalogue::standard(), options, m);
  EXPECT_NEAR(*m.number("current_a"), -21.93, 1e-9);
}

bool scaled(const FieldDesc& f) {
  return f.kind != FieldKind::kReserved && (f.scale != 1.0 || f.bias != 0.0);
}

// Adding a scaled or offset field to the catalogue without a hand-written vector fails here.
TEST(RawVectors, EveryScaledOrOffsetFieldHasAHandWrittenVector) {
  const auto& cat = Catalogue::standard();
  std::set<const FieldDesc*> covered;
  for (const auto& v : vectors()) {
    const auto data = hex(v.data);
    const MessageDesc* desc = cat.find(v.can_id, v.function, static_cast<uint8_t>(data.size()));
    ASSERT_NE(desc, nullptr) << v.what << ": not in the catalogue (or wrong length)";
    for (const auto& e : v.expect) {
      bool found = false;
      for (const auto& f : desc->fields) {
        if (f.name == e.field) {
          covered.insert(&f);
          found = true;
        }
      }
      EXPECT_TRUE(found) << v.what << ": no field " << e.field;
    }
  }
  std::size_t scaled_fields = 0;
  for (const auto& msg : cat.messages()) {
    for (const auto& f : msg.fields) {
      if (!scaled(f)) continue;
      ++scaled_fields;
      EXPECT_TRUE(covered.count(&f))
          << msg.name << " (0x" << std::hex << msg.can_id << "/0x" << msg.command() << ") field "
          << f.name << " has a scale or bias but no hand-written vector in test_raw_vectors.cc";
    }
  }
  EXPECT_GT(scaled_fields, 20u);  // the check itself looks at the real catalogue
}

}  // namespace
}  // namespace motinova
