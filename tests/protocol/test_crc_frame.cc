// Spec §2.3-2.5 test vectors: CRC32, full application frames and their segmentation.
#include <gtest/gtest.h>

#include <string>

#include "motinova/crc32.h"
#include "motinova/frame.h"
#include "motinova/segmenter.h"
#include "test_util.h"

namespace motinova {
namespace {

using test::hex;

TEST(Crc32, CheckValueOfAsciiDigits) {
  const std::string digits = "123456789";
  EXPECT_EQ(crc32({reinterpret_cast<const uint8_t*>(digits.data()), digits.size()}), 0x1556F485u);
}

TEST(Crc32, EmptyInputIsInitValue) {
  EXPECT_EQ(crc32({}), 0xFFFFFFFFu);
}

TEST(Crc32, IsNotZlibCrc) {
  // zlib's CRC-32 of "123456789" is 0xCBF43926; the MOTINOVA CRC must differ.
  const std::string digits = "123456789";
  EXPECT_NE(crc32({reinterpret_cast<const uint8_t*>(digits.data()), digits.size()}), 0xCBF43926u);
}

TEST(Crc32, UpdateIsIncremental) {
  const auto bytes = hex("55 AA 07 12 11 03 22 01 00");
  const uint32_t whole = crc32(bytes);
  const uint32_t split =
      crc32_update(crc32(std::span(bytes).first(4)), std::span(bytes).subspan(4));
  EXPECT_EQ(whole, split);
}

struct Vector {
  const char* name;
  uint16_t can_id;
  const char* crc_input;
  uint32_t crc;
  const char* frame;
};

// Spec §2.5, T1-T13 (big-endian CRC, the primary reading of U1).
const Vector kVectors[] = {
    {"T1", 0x712, "55 AA 07 12 11 03 22 01 00", 0x01295122, "55 AA 11 03 22 01 00 01 29 51 22 F0"},
    {"T2", 0x767, "55 AA 07 67 16 08 83 06 55 4E 4C 4F 43 4B", 0x840B4B96,
     "55 AA 16 08 83 06 55 4E 4C 4F 43 4B 84 0B 4B 96 F0"},
    {"T3", 0x767, "55 AA 07 67 16 06 82 04 4C 4F 43 4B", 0xE5C4613B,
     "55 AA 16 06 82 04 4C 4F 43 4B E5 C4 61 3B F0"},
    {"T4", 0x710, "55 AA 07 10 0C 07 13 05 52 45 41 44 59", 0x69427A43,
     "55 AA 0C 07 13 05 52 45 41 44 59 69 42 7A 43 F0"},
    {"T5", 0x710, "55 AA 07 10 0C 06 11 04 00 00 00 00", 0xF86A5E83,
     "55 AA 0C 06 11 04 00 00 00 00 F8 6A 5E 83 F0"},
    {"T6", 0x760, "55 AA 07 60 0C 06 11 04 4C 4F 43 4B", 0xEB70B9FC,
     "55 AA 0C 06 11 04 4C 4F 43 4B EB 70 B9 FC F0"},
    {"T7", 0x760, "55 AA 07 60 0C 0A 10 08 53 48 55 54 44 4F 57 4E", 0xF8FFC9A0,
     "55 AA 0C 0A 10 08 53 48 55 54 44 4F 57 4E F8 FF C9 A0 F0"},
    {"T8", 0x767, "55 AA 07 67 11 02 81 00", 0x201648F9, "55 AA 11 02 81 00 20 16 48 F9 F0"},
    {"T9", 0x761, "55 AA 07 61 16 04 30 02 02 F1", 0x7817E028,
     "55 AA 16 04 30 02 02 F1 78 17 E0 28 F0"},
    {"T10", 0x761, "55 AA 07 61 11 02 33 00", 0x4FC52932, "55 AA 11 02 33 00 4F C5 29 32 F0"},
    {"T11", 0x712, "55 AA 07 12 11 0B 30 09 48 41 4E 44 53 48 41 4B 45", 0x443E4058,
     "55 AA 11 0B 30 09 48 41 4E 44 53 48 41 4B 45 44 3E 40 58 F0"},
    {"T12", 0x721, "55 AA 07 21 0C 07 30 05 52 45 41 44 59", 0x310D885C,
     "55 AA 0C 07 30 05 52 45 41 44 59 31 0D 88 5C F0"},
    {"T13", 0x761, "55 AA 07 61 16 0A 34 08 00 02 00 00 F3 00 00 00", 0x558B3C60,
     "55 AA 16 0A 34 08 00 02 00 00 F3 00 00 00 55 8B 3C 60 F0"},
};

class SpecVector : public ::testing::TestWithParam<Vector> {};

TEST_P(SpecVector, RawCrcMatches) {
  const auto& v = GetParam();
  EXPECT_EQ(crc32(hex(v.crc_input)), v.crc) << v.name;
}

TEST_P(SpecVector, FrameCrcInsertsCanId) {
  const auto& v = GetParam();
  const auto frame = hex(v.frame);
  EXPECT_EQ(frame_crc(v.can_id, std::span(frame).first(frame.size() - 5)), v.crc) << v.name;
}

TEST_P(SpecVector, ParsesAndReencodesIdentically) {
  const auto& v = GetParam();
  const auto bytes = hex(v.frame);
  const ParseResult r = parse_frame(v.can_id, bytes, CrcOrder::kBig);
  ASSERT_TRUE(r.ok()) << v.name << ": " << frame_error_name(r.error);
  EXPECT_EQ(r.crc_seen, CrcOrder::kBig);
  EXPECT_EQ(r.frame.can_id, v.can_id);
  EXPECT_EQ(static_cast<uint8_t>(r.frame.mode), bytes[2]);
  EXPECT_EQ(r.frame.function, bytes[4]);
  EXPECT_EQ(r.frame.data.size(), bytes[5]);
  const auto encoded = encode_frame(r.frame, CrcOrder::kBig);
  EXPECT_EQ(std::vector<uint8_t>(encoded.begin(), encoded.end()), bytes) << v.name;
}

TEST_P(SpecVector, LittleEndianCrcIsTheByteReversal) {
  const auto& v = GetParam();
  auto bytes = hex(v.frame);
  std::reverse(bytes.end() - 5, bytes.end() - 1);
  EXPECT_FALSE(parse_frame(v.can_id, bytes, CrcOrder::kBig).ok());
  const auto le = parse_frame(v.can_id, bytes, CrcOrder::kLittle);
  ASSERT_TRUE(le.ok());
  const auto automatic = parse_frame(v.can_id, bytes, CrcOrder::kAuto);
  ASSERT_TRUE(automatic.ok());
  EXPECT_EQ(automatic.crc_seen, CrcOrder::kLittle);
  const auto encoded = encode_frame(le.frame, CrcOrder::kLittle);
  EXPECT_EQ(std::vector<uint8_t>(encoded.begin(), encoded.end()), bytes);
}

TEST_P(SpecVector, WrongCanIdFailsCrc) {
  const auto& v = GetParam();
  EXPECT_EQ(parse_frame(v.can_id ^ 0x001, hex(v.frame), CrcOrder::kAuto).error,
            FrameError::kBadCrc);
}

INSTANTIATE_TEST_SUITE_P(Spec, SpecVector, ::testing::ValuesIn(kVectors),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(SpecLittleEndianVectors, AsPrinted) {
  EXPECT_TRUE(
      parse_frame(0x712, hex("55 AA 11 03 22 01 00 22 51 29 01 F0"), CrcOrder::kLittle).ok());
  EXPECT_TRUE(parse_frame(0x767, hex("55 AA 16 08 83 06 55 4E 4C 4F 43 4B 96 4B 0B 84 F0"),
                          CrcOrder::kLittle)
                  .ok());
  EXPECT_TRUE(
      parse_frame(0x710, hex("55 AA 0C 07 13 05 52 45 41 44 59 43 7A 42 69 F0"), CrcOrder::kLittle)
          .ok());
}

// CDL<->APP link frames carry the ID inside the frame; their CRC is the plain CRC of everything
// from 55 AA to the end of DATA (§5.3).
TEST(CdlLinkVectors, CrcCoversEmbeddedId) {
  EXPECT_EQ(crc32(hex("55 AA 07 FF 11 02 11 00")), 0xABE8A727u);
  EXPECT_EQ(crc32(hex("55 AA 07 FF 0C 02 11 00")), 0x0130AF98u);
  EXPECT_EQ(crc32(hex("55 AA 07 FF 16 03 22 01 F1")), 0x185D39EEu);
  EXPECT_EQ(crc32(hex("55 AA 07 FF 16 03 22 01 F0")), 0x1C9C2459u);
}

TEST(DecoderVectors, FramesOfSpecSection25) {
  const auto mc = hex(
      "55 AA 0C 22 10 20 00 FD 0B B8 00 FA BB 80 14 50 46 1E 00 02 F1 50 00 41 04 D2 0C 4B 55 50 "
      "00 7B 07 08 00 00 00 00 50 B7 7A ED F0");
  const auto r = parse_frame(0x710, mc, CrcOrder::kBig);
  ASSERT_TRUE(r.ok()) << frame_error_name(r.error);
  EXPECT_EQ(r.frame.command(), 0x1020);
  const auto lock =
      hex("55 AA 0C 12 10 10 2E E0 00 96 41 02 00 01 00 00 00 00 00 00 00 00 3C 35 01 BD F0");
  const auto l = parse_frame(0x770, lock, CrcOrder::kBig);
  ASSERT_TRUE(l.ok());
  EXPECT_EQ(l.frame.command(), 0x1010);
}

TEST(Segmentation, SpecExamples) {
  struct Case {
    uint16_t id;
    const char* frame;
    std::vector<const char*> segments;
  };
  const Case cases[] = {
      {0x712, "55 AA 11 03 22 01 00 01 29 51 22 F0", {"55 AA 11 03 22 01 00 01", "29 51 22 F0"}},
      {0x767,
       "55 AA 16 08 83 06 55 4E 4C 4F 43 4B 84 0B 4B 96 F0",
       {"55 AA 16 08 83 06 55 4E", "4C 4F 43 4B 84 0B 4B 96", "F0"}},
      {0x710,
       "55 AA 0C 07 13 05 52 45 41 44 59 69 42 7A 43 F0",
       {"55 AA 0C 07 13 05 52 45", "41 44 59 69 42 7A 43 F0"}},
      {0x760,
       "55 AA 0C 0A 10 08 53 48 55 54 44 4F 57 4E F8 FF C9 A0 F0",
       {"55 AA 0C 0A 10 08 53 48", "55 54 44 4F 57 4E F8 FF", "C9 A0 F0"}},
  };
  for (const auto& c : cases) {
    const auto frames = segment(c.id, hex(c.frame));
    ASSERT_EQ(frames.size(), c.segments.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i], test::can_frame(c.id, c.segments[i])) << c.frame << " segment " << i;
    }
  }
}

TEST(Frame, LargestFrameIs33Segments) {
  AppFrame f;
  f.can_id = 0x715;
  f.mode = Mode::kReport;
  f.function = 0xAB;
  f.data.resize(kMaxData);
  EXPECT_EQ(encode_frame(f).size(), 264u);
  EXPECT_EQ(segment(f).size(), 33u);
}

TEST(Frame, ParseRejectsEachStructuralError) {
  const auto good = hex("55 AA 11 03 22 01 00 01 29 51 22 F0");
  auto mutate = [&](std::size_t i, uint8_t v) {
    auto b = good;
    b[i] = v;
    return parse_frame(0x712, b, CrcOrder::kBig).error;
  };
  EXPECT_EQ(mutate(0, 0x54), FrameError::kBadHeader);
  EXPECT_EQ(mutate(1, 0xAB), FrameError::kBadHeader);
  EXPECT_EQ(mutate(2, 0x12), FrameError::kBadMode);
  EXPECT_EQ(mutate(3, 0x01), FrameError::kBadLength);
  EXPECT_EQ(mutate(3, 0x04), FrameError::kTruncated);
  EXPECT_EQ(mutate(5, 0x02), FrameError::kLengthMismatch);
  EXPECT_EQ(mutate(11, 0xF1), FrameError::kBadTail);
  EXPECT_EQ(mutate(6, 0x01), FrameError::kBadCrc);
  EXPECT_EQ(parse_frame(0x712, std::span(good).first(7), CrcOrder::kBig).error,
            FrameError::kTruncated);
}

}  // namespace
}  // namespace motinova
