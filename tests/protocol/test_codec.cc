// decode() and MessageWriter: the spec §2.5 decoder vectors, every uncertain-reading option that
// changes a value, sentinels, fault-word normalisation, unknown / mis-sized messages, and the
// writer's validation errors.

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "motinova/codec.h"
#include "motinova/frame.h"
#include "test_util.h"

// Counts heap allocations so that "decode() never allocates" is a test that can fail. The
// malloc/free pair is the canonical replacement; GCC 12 misreads it after inlining.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
namespace {
std::atomic<long> g_allocations{0};
}  // namespace
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace motinova {
namespace {

using test::hex;

const Catalogue& cat() {
  return Catalogue::standard();
}

// Decoded enum names are views into the options: keep them alive for the whole test.
const DecodeOptions kDefaults{};

AppFrame parse(uint16_t id, std::string_view bytes) {
  const ParseResult r = parse_frame(id, hex(bytes), CrcOrder::kBig);
  EXPECT_TRUE(r.ok()) << frame_error_name(r.error);
  return r.frame;
}

AppFrame frame_of(uint16_t id, Mode mode, uint8_t function, std::string_view data_hex) {
  const auto data = hex(data_hex);
  AppFrame f;
  f.can_id = id;
  f.mode = mode;
  f.function = function;
  f.data.assign(data);
  return f;
}

// Spec §2.5 decoder vectors.
constexpr std::string_view kMcRunning =
    "55 AA 0C 22 10 20 00 FD 0B B8 00 FA BB 80 14 50 46 1E 00 02 F1 50 00 41 04 D2 0C 4B 55 50 "
    "00 7B 07 08 00 00 00 00 50 B7 7A ED F0";
constexpr std::string_view kLock1Status =
    "55 AA 0C 12 10 10 2E E0 00 96 41 02 00 01 00 00 00 00 00 00 00 00 3C 35 01 BD F0";
// The MC running data DATA on its own, for variants.
constexpr std::string_view kMcData =
    "00 FD 0B B8 00 FA BB 80 14 50 46 1E 00 02 F1 50 00 41 04 D2 0C 4B 55 50 00 7B 07 08 00 00 "
    "00 00";

TEST(Decode, McRunningDataVector) {
  const AppFrame frame = parse(0x710, kMcRunning);
  DecodedMessage m;
  decode(frame, cat(), kDefaults, m);
  ASSERT_EQ(m.status, DecodeStatus::kOk);
  EXPECT_EQ(m.name(), "mc_status");
  EXPECT_TRUE(m.mode_matches);
  EXPECT_EQ(m.frame, &frame);
  EXPECT_NEAR(*m.number("speed_kmh"), 25.3, 1e-9);
  EXPECT_EQ(*m.number("motor_rpm"), 3000);
  EXPECT_EQ(*m.number("power_w"), 250);
  EXPECT_NEAR(*m.number("voltage_v"), 48.0, 1e-9);
  EXPECT_NEAR(*m.number("current_a"), 5.2, 1e-9);
  EXPECT_EQ(*m.number("cadence_rpm"), 70);
  EXPECT_EQ(*m.number("torque_nm"), 30);
  EXPECT_EQ(*m.raw("direction"), 0);
  EXPECT_EQ(m.text("direction"), "forward");
  EXPECT_EQ(*m.raw("assist"), 2);
  EXPECT_EQ(m.text("assist"), "norm");
  EXPECT_EQ(*m.number("headlight"), 1.0);
  EXPECT_EQ(*m.number("soc_pct"), 80);
  EXPECT_EQ(*m.number("range_km"), 65);
  EXPECT_EQ(*m.number("odo_km"), 1234);
  EXPECT_NEAR(*m.number("consumption_ah_per_km"), 0.12, 1e-9);
  EXPECT_EQ(*m.number("pcb_temp_c"), 35);
  EXPECT_EQ(*m.number("motor_temp_c"), 45);
  EXPECT_EQ(*m.number("mcu_temp_c"), 40);
  EXPECT_NEAR(*m.number("trip_km"), 12.3, 1e-9);
  EXPECT_EQ(*m.number("trip_time_s"), 1800);
  EXPECT_EQ(*m.raw("status_flags"), 0);
  EXPECT_EQ(m.values().size(), 20u);  // reserved bytes are not exposed
  EXPECT_EQ(m.find("reserved"), nullptr);
}

TEST(Decode, Lock1StatusVector) {
  const AppFrame frame = parse(0x770, kLock1Status);
  DecodedMessage m;
  decode(frame, cat(), kDefaults, m);
  ASSERT_EQ(m.status, DecodeStatus::kOk);
  EXPECT_EQ(m.name(), "lock_status");
  EXPECT_NEAR(*m.number("voltage_v"), 12.0, 1e-9);
  EXPECT_NEAR(*m.number("current_a"), 0.150, 1e-9);
  EXPECT_EQ(*m.number("temp_c"), 25);
  EXPECT_EQ(*m.raw("state"), 2);
  EXPECT_EQ(m.text("state"), "locked");
  EXPECT_EQ(m.find("state")->field->enum_style, EnumStyle::kNameThenRaw);
  EXPECT_EQ(*m.raw("bolts"), 1);
  EXPECT_EQ(m.find("motor_rpm"), nullptr);  // only LOCK 4 has it
}

TEST(Decode, Lock4HasMotorRpm) {
  DecodedMessage m;
  const AppFrame f =
      frame_of(0x7A0, Mode::kReport, 0x10, "2E E0 00 96 41 01 00 03 01 F4 00 00 00 00 00 00");
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(*m.number("motor_rpm"), 500);
  EXPECT_EQ(m.text("state"), "unlocked");
}

TEST(Decode, OptionTablesNameEnums) {
  DecodeOptions options;
  options.lock_state_names[2] = "closed";
  options.assist_names[2].name = "normal";
  DecodedMessage m;
  const AppFrame lock = parse(0x770, kLock1Status);
  decode(lock, cat(), options, m);
  EXPECT_EQ(m.text("state"), "closed");
  const AppFrame mc = parse(0x710, kMcRunning);
  decode(mc, cat(), options, m);
  EXPECT_EQ(m.text("assist"), "normal");
  // Values without a name keep their raw value and an empty name (JSON shows 0xNN).
  const AppFrame odd = frame_of(0x761, Mode::kWrite, 0x30, "07 F0");
  decode(odd, cat(), options, m);
  EXPECT_EQ(*m.raw("assist"), 7);
  EXPECT_EQ(m.text("assist"), "");
  EXPECT_EQ(*m.number("headlight"), 0.0);
  const AppFrame state9 =
      frame_of(0x780, Mode::kReport, 0x10, "2E E0 00 96 41 09 00 01 00 00 00 00 00 00 00 00");
  decode(state9, cat(), options, m);
  EXPECT_EQ(*m.raw("state"), 9);
  EXPECT_EQ(m.text("state"), "");
}

TEST(Decode, LittleEndianDataOption) {
  const AppFrame le =
      frame_of(0x770, Mode::kReport, 0x10, "E0 2E 96 00 41 02 01 00 00 00 00 00 00 00 00 00");
  DecodeOptions options;
  options.data_order = ByteOrder::kLittle;
  DecodedMessage m;
  decode(le, cat(), options, m);
  EXPECT_NEAR(*m.number("voltage_v"), 12.0, 1e-9);
  EXPECT_NEAR(*m.number("current_a"), 0.150, 1e-9);
  EXPECT_EQ(*m.raw("bolts"), 1);
  EXPECT_EQ(m.data_order, ByteOrder::kLittle);
  // The same bytes read big-endian give the implausible value U2's range check catches.
  decode(le, cat(), kDefaults, m);
  EXPECT_NEAR(*m.number("voltage_v"), 57.390, 1e-9);
}

TEST(Decode, CellArrayElementsFollowDataOrder) {
  std::string data;
  for (int i = 0; i < 16; ++i) data += i < 13 ? "0F A0 " : "00 00 ";  // 4000 mV, 13S pack
  const AppFrame f = frame_of(0x720, Mode::kReport, 0x11, data);
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(*m.element("cells_mv", 0), 4000u);
  EXPECT_EQ(*m.element("cells_mv", 12), 4000u);
  EXPECT_EQ(*m.element("cells_mv", 13), 0u);
  EXPECT_FALSE(m.element("cells_mv", 16).has_value());
  EXPECT_FALSE(m.number("cells_mv").has_value());
  DecodeOptions le;
  le.data_order = ByteOrder::kLittle;
  decode(f, cat(), le, m);
  EXPECT_EQ(*m.element("cells_mv", 0), 0xA00Fu);
}

TEST(Decode, BmsCurrentSignOption) {
  // -200 mA on the wire (s16 0xFF38), charging flag set, state flags 0x03.
  const AppFrame f =
      frame_of(0x720, Mode::kReport, 0x10, "9C 40 FF 38 27 10 4E 20 41 32 03 62 00 0A 00 5A");
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  EXPECT_NEAR(*m.number("voltage_v"), 40.0, 1e-9);
  EXPECT_NEAR(*m.number("current_a"), -0.2, 1e-9);
  EXPECT_EQ(*m.raw("current_a"), -200);
  EXPECT_EQ(*m.number("charging"), 1.0);
  EXPECT_EQ(*m.raw("state_flags"), 3);
  EXPECT_EQ(*m.number("soh_pct"), 98);
  EXPECT_EQ(*m.number("cycles"), 10);
  EXPECT_EQ(*m.number("charge_time_min"), 90);
  DecodeOptions flipped;
  flipped.bms_current_charge_positive = false;
  decode(f, cat(), flipped, m);
  EXPECT_NEAR(*m.number("current_a"), 0.2, 1e-9);
  EXPECT_EQ(*m.raw("current_a"), -200);  // raw stays the wire value
}

TEST(Decode, McCurrentSignedOption) {
  std::string data(kMcData);
  data.replace(data.find("14 50"), 5, "FF 38");
  const AppFrame f = frame_of(0x710, Mode::kReport, 0x10, data);
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  EXPECT_NEAR(*m.number("current_a"), 65.336, 1e-9);
  DecodeOptions signed_current;
  signed_current.mc_current_signed = true;
  decode(f, cat(), signed_current, m);
  EXPECT_NEAR(*m.number("current_a"), -0.2, 1e-9);
}

TEST(Decode, McVoltageCurrentOrderOption) {
  const AppFrame documented = frame_of(0x710, Mode::kReport, 0x10, kMcData);
  std::string swapped_data(kMcData);
  swapped_data.replace(swapped_data.find("BB 80 14 50"), 11, "14 50 BB 80");
  const AppFrame swapped = frame_of(0x710, Mode::kReport, 0x10, swapped_data);
  DecodedMessage m;

  DecodeOptions current_first;
  current_first.mc_voltage_current_order = McVoltageCurrentOrder::kCurrentFirst;
  decode(swapped, cat(), current_first, m);
  EXPECT_NEAR(*m.number("voltage_v"), 48.0, 1e-9);
  EXPECT_NEAR(*m.number("current_a"), 5.2, 1e-9);
  decode(documented, cat(), current_first, m);
  EXPECT_NEAR(*m.number("voltage_v"), 5.2, 1e-9);

  DecodeOptions automatic;
  automatic.mc_voltage_current_order = McVoltageCurrentOrder::kAuto;
  for (const AppFrame* f : {&documented, &swapped}) {
    decode(*f, cat(), automatic, m);
    EXPECT_NEAR(*m.number("voltage_v"), 48.0, 1e-9);
    EXPECT_NEAR(*m.number("current_a"), 5.2, 1e-9);
  }
}

TEST(Decode, InvalidSentinelsDecodeAsInvalid) {
  std::string data(kMcData);
  data.replace(data.find("F1 50 00 41 04 D2 0C"), 20, "00 FF FF FF 04 D2 FF");
  const AppFrame f = frame_of(0x710, Mode::kReport, 0x10, data);
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  for (std::string_view name : {"soc_pct", "range_km", "consumption_ah_per_km", "headlight"}) {
    SCOPED_TRACE(name);
    const FieldValue* v = m.find(name);
    ASSERT_NE(v, nullptr);
    EXPECT_FALSE(v->valid);
    EXPECT_FALSE(m.number(name).has_value());
    EXPECT_TRUE(m.raw(name).has_value());
  }
  EXPECT_EQ(*m.raw("range_km"), 0xFFFF);
  EXPECT_EQ(*m.number("odo_km"), 1234);  // neighbours unaffected
}

TEST(Decode, KeywordMessages) {
  DecodedMessage m;
  const AppFrame ready = parse(0x710, "55 AA 0C 07 13 05 52 45 41 44 59 69 42 7A 43 F0");
  decode(ready, cat(), kDefaults, m);
  EXPECT_EQ(m.name(), "ready");
  EXPECT_EQ(m.desc->kind, MessageKind::kKeyword);
  EXPECT_EQ(m.text("keyword"), "READY");
  EXPECT_TRUE(m.find("keyword")->valid);

  const AppFrame wrong = frame_of(0x710, Mode::kReport, 0x13, "52 45 41 44 58");  // "READX"
  decode(wrong, cat(), kDefaults, m);
  EXPECT_EQ(m.name(), "ready");
  EXPECT_EQ(m.text("keyword"), "READX");
  EXPECT_FALSE(m.find("keyword")->valid);
}

TEST(Decode, ModelInfoTrimsPadding) {
  std::string block;
  auto field = [&](std::string_view s) {
    std::string f(s);
    f.resize(16, ' ');
    block += f;
  };
  field("MN-IOT-4G");
  field("SN0001");
  field("V1.0");
  field("V1.2.3_20240131");
  const AppFrame f = make_frame(0x760, Mode::kReport, 0x13, std::string_view(block));
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(m.name(), "device_info");
  EXPECT_EQ(m.text("model"), "MN-IOT-4G");
  EXPECT_EQ(m.text("serial"), "SN0001");
  EXPECT_EQ(m.text("hw"), "V1.0");
  EXPECT_EQ(m.text("fw"), "V1.2.3_20240131");
}

TEST(Decode, UnknownMessage) {
  DecodedMessage m;
  const AppFrame f = frame_of(0x710, Mode::kReport, 0x99, "01 02");
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(m.status, DecodeStatus::kUnknownMessage);
  EXPECT_EQ(m.desc, nullptr);
  EXPECT_EQ(m.name(), "unknown");
  EXPECT_TRUE(m.values().empty());
  EXPECT_EQ(m.frame, &f);
  const AppFrame other_id = frame_of(0x7F0, Mode::kReport, 0x10, "");
  decode(other_id, cat(), kDefaults, m);
  EXPECT_EQ(m.status, DecodeStatus::kUnknownMessage);
}

TEST(Decode, LengthMismatchIsReportedAsUnknown) {
  // A previous decode must not leak values into this one.
  DecodedMessage m;
  const AppFrame good = parse(0x710, kMcRunning);
  decode(good, cat(), kDefaults, m);
  std::string data(kMcData);
  data.resize(data.size() - 3);  // 31 bytes
  const AppFrame f = frame_of(0x710, Mode::kReport, 0x10, data);
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(m.status, DecodeStatus::kLengthMismatch);
  EXPECT_EQ(m.desc, nullptr);
  EXPECT_EQ(m.name(), "unknown");
  EXPECT_TRUE(m.values().empty());
}

TEST(Decode, ModeMismatchIsFlaggedButDecoded) {
  const AppFrame f = frame_of(0x761, Mode::kReport, 0x30, "02 F1");  // catalogue: write
  DecodedMessage m;
  decode(f, cat(), kDefaults, m);
  EXPECT_EQ(m.status, DecodeStatus::kOk);
  EXPECT_FALSE(m.mode_matches);
  EXPECT_EQ(*m.raw("assist"), 2);
}

TEST(Decode, DoesNotAllocate) {
  const AppFrame frames[] = {parse(0x710, kMcRunning), parse(0x770, kLock1Status),
                             frame_of(0x710, Mode::kReport, 0x11, "00 01 00 20"),
                             frame_of(0x710, Mode::kReport, 0x99, "")};
  DecodedMessage m;
  const DecodeOptions options;
  (void)Catalogue::standard();
  const long before = g_allocations.load();
  for (const AppFrame& f : frames) decode(f, cat(), options, m);
  EXPECT_EQ(g_allocations.load(), before);
  // The counter itself works: an allocation is seen.
  auto probe = std::make_unique<int>(1);
  EXPECT_GT(g_allocations.load(), before);
}

// --- fault words (U3) ------------------------------------------------------------------------

TEST(FaultWord, ThreeLayoutsNormaliseToTheSameWord) {
  // MOS short (documented high 0x0001) + speed sensor (low 0x0020).
  constexpr uint32_t kWord = 0x00010020;
  struct Case {
    FaultWordLayout layout;
    ByteOrder order;
    std::array<uint8_t, 4> wire;
  };
  const Case cases[] = {
      {FaultWordLayout::kDocumented, ByteOrder::kBig, {0x00, 0x01, 0x00, 0x20}},
      {FaultWordLayout::kDocumented, ByteOrder::kLittle, {0x20, 0x00, 0x01, 0x00}},
      {FaultWordLayout::kSwappedGroups, ByteOrder::kBig, {0x00, 0x20, 0x00, 0x01}},
      {FaultWordLayout::kSwappedGroups, ByteOrder::kLittle, {0x01, 0x00, 0x20, 0x00}},
      {FaultWordLayout::kTwoWordsLowFirst, ByteOrder::kBig, {0x00, 0x20, 0x00, 0x01}},
      {FaultWordLayout::kTwoWordsLowFirst, ByteOrder::kLittle, {0x20, 0x00, 0x01, 0x00}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(static_cast<int>(c.layout) * 10 + static_cast<int>(c.order));
    EXPECT_EQ(normalise_fault_word(std::span<const uint8_t, 4>(c.wire), c.order, c.layout), kWord);
    std::array<uint8_t, 4> out{};
    write_fault_word(kWord, c.order, c.layout, out);
    EXPECT_EQ(out, c.wire);
  }
}

TEST(FaultWord, LayoutOptionIsPerSource) {
  DecodeOptions options;
  options.mc_fault_layout = FaultWordLayout::kSwappedGroups;
  EXPECT_EQ(fault_layout_for(FaultSource::kMc, options), FaultWordLayout::kSwappedGroups);
  EXPECT_EQ(fault_layout_for(FaultSource::kBms, options), FaultWordLayout::kDocumented);
  options.other_fault_layout = FaultWordLayout::kTwoWordsLowFirst;
  for (FaultSource s :
       {FaultSource::kObc, FaultSource::kIot, FaultSource::kLock, FaultSource::kHmi}) {
    EXPECT_EQ(fault_layout_for(s, options), FaultWordLayout::kTwoWordsLowFirst);
  }

  const AppFrame mc = frame_of(0x710, Mode::kReport, 0x11, "00 20 00 01");
  DecodedMessage m;
  decode(mc, cat(), options, m);
  EXPECT_EQ(m.name(), "mc_faults");
  EXPECT_EQ(*m.raw("raw"), 0x00010020);
  decode(mc, cat(), kDefaults, m);
  EXPECT_EQ(*m.raw("raw"), 0x00200001);

  const AppFrame lock = frame_of(0x790, Mode::kReport, 0x11, "00 04 00 00");
  decode(lock, cat(), options, m);
  EXPECT_EQ(m.name(), "lock_faults");
  EXPECT_EQ(*m.raw("raw"), 0x00000004);  // two words, low first
}

// --- MessageWriter ----------------------------------------------------------------------------

std::vector<uint8_t> encoded(const AppFrame& f) {
  const auto bytes = encode_frame(f, CrcOrder::kBig);
  return {bytes.begin(), bytes.end()};
}

TEST(Writer, ReproducesSpecCommandVectors) {
  const DecodeOptions options;
  // T9: IOT -> MC set assist NORM + light on.
  const AppFrame t9 = MessageWriter(*cat().find("set_assist", 0x761), options)
                          .text("assist", "norm")
                          .boolean("headlight", true)
                          .frame();
  EXPECT_EQ(encoded(t9), hex("55 AA 16 04 30 02 02 F1 78 17 E0 28 F0"));
  // T13: write MC settings, speed-limit offset -13, mode 2.
  const AppFrame t13 = MessageWriter(*cat().find("write_mc_settings", 0x761), options)
                           .raw("mode", 2)
                           .value("speed_limit_offset_kmh", -13)
                           .frame();
  EXPECT_EQ(encoded(t13), hex("55 AA 16 0A 34 08 00 02 00 00 F3 00 00 00 55 8B 3C 60 F0"));
  // T2 / T3 / T8: lock 1 commands; keywords are pre-filled.
  EXPECT_EQ(encoded(MessageWriter(*cat().find("unlock", 0x767), options).frame()),
            hex("55 AA 16 08 83 06 55 4E 4C 4F 43 4B 84 0B 4B 96 F0"));
  EXPECT_EQ(encoded(MessageWriter(*cat().find("lock", 0x767), options).frame()),
            hex("55 AA 16 06 82 04 4C 4F 43 4B E5 C4 61 3B F0"));
  EXPECT_EQ(encoded(MessageWriter(*cat().find("read_lock_status", 0x767), options).frame()),
            hex("55 AA 11 02 81 00 20 16 48 F9 F0"));
  // T7: IOT SHUTDOWN broadcast; T11: MC HANDSHAKE.
  EXPECT_EQ(encoded(MessageWriter(*cat().find(0x760, 0x10), options).frame()),
            hex("55 AA 0C 0A 10 08 53 48 55 54 44 4F 57 4E F8 FF C9 A0 F0"));
  EXPECT_EQ(encoded(MessageWriter(*cat().find(0x712, 0x30), options).frame()),
            hex("55 AA 11 0B 30 09 48 41 4E 44 53 48 41 4B 45 44 3E 40 58 F0"));
}

TEST(Writer, McRunningDataVectorFromPhysicalValues) {
  const DecodeOptions options;
  MessageWriter w(*cat().find(0x710, 0x10), options);
  w.value("speed_kmh", 25.3).value("motor_rpm", 3000).value("power_w", 250);
  w.value("voltage_v", 48.0).value("current_a", 5.2).value("cadence_rpm", 70);
  w.value("torque_nm", 30).text("direction", "forward").text("assist", "norm");
  w.boolean("headlight", true).value("soc_pct", 80).value("range_km", 65);
  w.value("odo_km", 1234).value("consumption_ah_per_km", 0.12).value("pcb_temp_c", 35);
  w.value("motor_temp_c", 45).value("mcu_temp_c", 40).value("trip_km", 12.3);
  w.value("trip_time_s", 1800);
  EXPECT_EQ(encoded(w.frame()), hex(kMcRunning));
}

TEST(Writer, OptionsShapeTheWire) {
  DecodeOptions options;
  options.data_order = ByteOrder::kLittle;
  options.bms_current_charge_positive = false;
  const AppFrame bms = MessageWriter(*cat().find(0x720, 0x10), options)
                           .value("voltage_v", 40.0)
                           .value("current_a", 0.2)  // discharge-positive bus: wire -200
                           .frame();
  EXPECT_EQ(bms.data[0], 0x40);
  EXPECT_EQ(bms.data[1], 0x9C);
  EXPECT_EQ(bms.data[2], 0x38);
  EXPECT_EQ(bms.data[3], 0xFF);

  DecodeOptions current_first;
  current_first.mc_voltage_current_order = McVoltageCurrentOrder::kCurrentFirst;
  const AppFrame mc = MessageWriter(*cat().find(0x710, 0x10), current_first)
                          .value("voltage_v", 48.0)
                          .value("current_a", 5.2)
                          .frame();
  EXPECT_EQ(mc.data[6], 0x14);  // current 5200 mA at offset 6
  EXPECT_EQ(mc.data[8], 0xBB);  // voltage 48000 mV at offset 8
  DecodedMessage m;
  decode(mc, cat(), current_first, m);
  EXPECT_NEAR(*m.number("voltage_v"), 48.0, 1e-9);
}

TEST(Writer, MaskedBooleanKeepsOtherBits) {
  const DecodeOptions options;
  const AppFrame f = MessageWriter(*cat().find(0x720, 0x10), options)
                         .raw("state_flags", 0x82)
                         .boolean("charging", true)
                         .frame();
  EXPECT_EQ(f.data[10], 0x83);
  const AppFrame g = MessageWriter(*cat().find(0x720, 0x10), options)
                         .raw("state_flags", 0x83)
                         .boolean("charging", false)
                         .frame();
  EXPECT_EQ(g.data[10], 0x82);
}

TEST(Writer, TextIsSpacePaddedAndFrameCanMoveToAnotherId) {
  const DecodeOptions options;
  MessageWriter w(*cat().find(0x770, 0x12), options);
  w.text("model", "LOCK-A").text("fw", "V1.0.0_20240101");
  const AppFrame f = w.frame(0x790);
  EXPECT_EQ(f.can_id, 0x790);
  EXPECT_EQ(f.function, 0x12);
  EXPECT_EQ(f.data.size(), 64u);
  EXPECT_EQ(f.data[6], ' ');
  EXPECT_EQ(f.data[16], ' ');  // unset serial: spaces
  DecodedMessage m;
  decode(f, cat(), options, m);
  EXPECT_EQ(m.text("model"), "LOCK-A");
  EXPECT_EQ(m.text("serial"), "");
  EXPECT_EQ(m.text("fw"), "V1.0.0_20240101");
}

// Runs `fn`, expects std::invalid_argument whose text contains every `needle`.
template <typename Fn>
void expect_rejected(Fn&& fn, std::initializer_list<std::string_view> needles) {
  try {
    fn();
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    for (std::string_view n : needles) {
      EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
    }
  }
}

TEST(Writer, RejectsBadInputNamingMessageAndField) {
  const DecodeOptions options;
  const MessageDesc& mc = *cat().find(0x710, 0x10);
  const MessageDesc& settings = *cat().find(0x761, 0x34);
  const MessageDesc& info = *cat().find(0x760, 0x13);
  const MessageDesc& cells = *cat().find(0x720, 0x11);

  expect_rejected([&] { MessageWriter(mc, options).raw("speed", 1); },
                  {"mc_status", "0x710/0x1020", "'speed'"});
  expect_rejected([&] { MessageWriter(mc, options).raw("reserved", 0); }, {"'reserved'"});
  expect_rejected([&] { MessageWriter(mc, options).raw("soc_pct", 256); },
                  {"mc_status", "'soc_pct'", "256", "0..255"});
  expect_rejected([&] { MessageWriter(mc, options).raw("soc_pct", -1); }, {"'soc_pct'"});
  expect_rejected([&] { MessageWriter(mc, options).value("speed_kmh", 7000.0); },
                  {"'speed_kmh'", "0..65535"});
  expect_rejected([&] { MessageWriter(mc, options).value("speed_kmh", std::nan("")); },
                  {"'speed_kmh'", "not finite"});
  expect_rejected([&] { MessageWriter(mc, options).value("speed_kmh", 1e300); },
                  {"'speed_kmh'", "out of range"});
  expect_rejected([&] { MessageWriter(mc, options).boolean("soc_pct", true); },
                  {"'soc_pct'", "not a boolean"});
  expect_rejected([&] { MessageWriter(mc, options).text("assist", "warp"); },
                  {"'assist'", "'warp'"});
  expect_rejected([&] { MessageWriter(settings, options).raw("speed_limit_offset_kmh", -129); },
                  {"write_mc_settings", "'speed_limit_offset_kmh'", "-128..127"});
  expect_rejected([&] { MessageWriter(settings, options).raw("speed_limit_offset_kmh", 0xF3); },
                  {"'speed_limit_offset_kmh'"});
  expect_rejected([&] { MessageWriter(info, options).text("model", "ABCDEFGHIJKLMNOPQ"); },
                  {"device_info", "'model'", "17", "16"});
  expect_rejected([&] { MessageWriter(info, options).text("model", "bad\n"); },
                  {"'model'", "non-printable", "position 3"});
  expect_rejected([&] { MessageWriter(info, options).raw("model", 1); },
                  {"'model'", "not an integer"});
  expect_rejected([&] { MessageWriter(cells, options).element("cells_mv", 16, 1); },
                  {"bms_cells", "'cells_mv'", "index 16"});
  expect_rejected([&] { MessageWriter(cells, options).element("cells_mv", 0, 0x10000); },
                  {"'cells_mv'", "65536"});
  expect_rejected([&] { MessageWriter(*cat().find(0x710, 0x11), options).raw("raw", -1); },
                  {"mc_faults", "'raw'"});
}

}  // namespace
}  // namespace motinova
