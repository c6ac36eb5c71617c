// candump -L reader/writer: round trips, every error kind with its line and column, and the
// LineReader carrying on past bad lines. Also the shared error-frame interpretation.
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "gateway/can/candump.h"
#include "gateway/can/error_frame.h"

namespace fleetgw::can {
namespace {

using candump::format_line;
using candump::format_record;
using candump::FrameKind;
using candump::parse_line;
using motinova::CanFrame;
using motinova::Micros;

CanFrame frame(uint32_t id, std::vector<uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<uint8_t>(bytes.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) f.data[i] = bytes[i];
  return f;
}

TEST(Candump, ParsesStandardDataFrame) {
  const auto r = parse_line("(1763700000.123456) can0 710#55AA0C22", 1);
  ASSERT_TRUE(r.ok()) << r.error->message;
  ASSERT_TRUE(r.record);
  EXPECT_EQ(r.record->timestamp, Micros{1763700000123456});
  EXPECT_EQ(r.record->interface, "can0");
  EXPECT_EQ(r.record->frame, frame(0x710, {0x55, 0xAA, 0x0C, 0x22}));
  EXPECT_EQ(r.record->kind, FrameKind::kData);
  EXPECT_FALSE(r.record->extended);
  EXPECT_TRUE(r.record->is_standard_data());
}

TEST(Candump, FormatThenParseRoundTripsByteForByte) {
  const std::vector<std::string> lines = {
      "(1763700000.123456) can0 710#55AA0C22",
      "(0000000001.000001) vcan0 7FF#",
      "(1763700000.000000) can0 762#0102030405060708",
      "(1763700000.999999) can1 12345678#DEADBEEF",
      "(1763700001.000000) can0 710#R",
      "(1763700001.000000) can0 710#R4",
      "(1763700002.500000) can0 20000040#0000000000000000",
  };
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const auto r = parse_line(lines[i], i + 1);
    ASSERT_TRUE(r.record) << lines[i] << ": " << (r.error ? r.error->message : "blank");
    EXPECT_EQ(format_record(*r.record), lines[i]);
  }
}

TEST(Candump, FormatLineWritesCandumpLayout) {
  EXPECT_EQ(format_line(Micros{1763700000123456}, "can0", frame(0x716, {0x01, 0xAB})),
            "(1763700000.123456) can0 716#01AB");
  EXPECT_EQ(format_line(Micros{5}, "vcan0", frame(0x700, {})), "(0000000000.000005) vcan0 700#");
  EXPECT_THROW(format_line(Micros{-1}, "can0", frame(0x700, {})), std::invalid_argument);
  EXPECT_THROW(format_line(Micros{0}, "can0", frame(0x800, {})), std::invalid_argument);
  CanFrame too_long = frame(0x700, {});
  too_long.len = 9;
  EXPECT_THROW(format_line(Micros{0}, "can0", too_long), std::invalid_argument);
}

TEST(Candump, AcceptsVariants) {
  // Dot separators (cansend syntax), lower-case hex, CRLF, trailing direction, nanoseconds.
  auto r = parse_line("(1.5) can0 710#01.02.ab\r", 3);
  ASSERT_TRUE(r.record) << r.error->message;
  EXPECT_EQ(r.record->timestamp, Micros{1'500'000});
  EXPECT_EQ(r.record->frame, frame(0x710, {0x01, 0x02, 0xAB}));

  r = parse_line("(1763700000.123456789) can0 710#00 R", 4);
  ASSERT_TRUE(r.record) << r.error->message;
  EXPECT_EQ(r.record->timestamp, Micros{1763700000123456});

  r = parse_line("(1763700000.123456) can0 710#0011223344556677_C", 5);
  ASSERT_TRUE(r.record) << r.error->message;
  EXPECT_EQ(r.record->frame.len, 8);
}

TEST(Candump, RemoteExtendedAndErrorFrames) {
  auto r = parse_line("(1.000000) can0 123#R", 1);
  ASSERT_TRUE(r.record);
  EXPECT_EQ(r.record->kind, FrameKind::kRemote);
  EXPECT_EQ(r.record->frame.len, 0);
  EXPECT_EQ(r.record->socketcan_id(), 0x123U | candump::kRtrFlag);
  EXPECT_FALSE(r.record->is_standard_data());

  r = parse_line("(1.000000) can0 18FF50E5#01", 2);
  ASSERT_TRUE(r.record);
  EXPECT_TRUE(r.record->extended);
  EXPECT_EQ(r.record->frame.id, 0x18FF50E5U);
  EXPECT_EQ(r.record->socketcan_id(), 0x18FF50E5U | candump::kEffFlag);
  EXPECT_FALSE(r.record->is_standard_data());

  r = parse_line("(1.000000) can0 20000004#0004000000000000", 3);
  ASSERT_TRUE(r.record);
  EXPECT_EQ(r.record->kind, FrameKind::kError);
  EXPECT_EQ(r.record->frame.id, 0x4U);  // CAN_ERR_CRTL
  EXPECT_EQ(r.record->frame.data[1], 0x04);
}

TEST(Candump, BlankAndCommentLinesAreNeitherRecordNorError) {
  for (const char* line : {"", "   ", "\r", "# recorded on bike 42"}) {
    const auto r = parse_line(line, 1);
    EXPECT_TRUE(r.ok()) << line;
    EXPECT_FALSE(r.record) << line;
  }
}

struct BadLine {
  const char* line;
  std::size_t column;
  const char* what;
};

class CandumpErrors : public ::testing::TestWithParam<BadLine> {};

TEST_P(CandumpErrors, NamesLineColumnAndProblem) {
  const BadLine& c = GetParam();
  const auto r = parse_line(c.line, 17);
  ASSERT_FALSE(r.ok()) << c.line;
  EXPECT_FALSE(r.record);
  EXPECT_EQ(r.error->line, 17U);
  EXPECT_EQ(r.error->column, c.column) << r.error->message;
  const std::string prefix = "line 17, column " + std::to_string(c.column) + ": ";
  EXPECT_EQ(r.error->message.rfind(prefix, 0), 0U) << r.error->message;
  EXPECT_NE(r.error->message.find(c.what), std::string::npos) << r.error->message;
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, CandumpErrors,
    ::testing::Values(
        BadLine{"1763700000.123456 can0 710#00", 1, "expected '('"},
        BadLine{"(x) can0 710#00", 2, "expected digits"},
        BadLine{"(1763700000) can0 710#00", 12, "expected '.'"},
        BadLine{"(1763700000.) can0 710#00", 13, "expected digits after '.'"},
        BadLine{"(1763700000.123456 can0 710#00", 19, "expected ')'"},
        BadLine{"(1763700000.123456)can0 710#00", 20, "expected a space"},
        BadLine{"(1763700000.123456)", 20, "missing interface"},
        BadLine{"(1763700000.123456) can0", 25, "missing frame"},
        BadLine{"(1763700000.123456) can0 71055AA", 26, "missing '#'"},
        BadLine{"(1763700000.123456) can0 7100#55", 26, "3 (standard) or 8 (extended)"},
        BadLine{"(1763700000.123456) can0 7G0#55", 27, "invalid hex digit 'G' in CAN ID"},
        BadLine{"(1763700000.123456) can0 800#55", 26, "exceeds 0x7FF"},
        BadLine{"(1763700000.123456) can0 5FFFFFFF#55", 26, "exceeds 29 bits"},
        BadLine{"(1763700000.123456) can0 A0000001#55", 26, "also carries EFF/RTR"},
        BadLine{"(1763700000.123456) can0 710#55AA0", 34, "odd number of hex digits in payload"},
        BadLine{"(1763700000.123456) can0 710#5X", 31, "invalid character 'X' in payload"},
        BadLine{"(1763700000.123456) can0 710#001122334455667788", 46, "longer than 8 bytes"},
        BadLine{"(1763700000.123456) can0 710##1001122", 30,
                "CAN FD frame ('##') is not supported"},
        BadLine{"(1763700000.123456) can0 710#R9", 31, "DLC must be a single digit"},
        BadLine{"(1763700000.123456) can0 20000004#R", 35, "cannot be a remote"},
        BadLine{"(1763700000.123456) can0 710#00 garbage", 33, "unexpected text 'garbage'"},
        BadLine{"(1763700000.123456) averyveryverylongname 710#00", 21, "longer than 15"}));

TEST(Candump, FdLineIsMarkedUnsupported) {
  const auto r = parse_line("(1.000000) can0 710##1001122", 9);
  ASSERT_TRUE(r.error);
  EXPECT_TRUE(r.error->unsupported);
  const auto bad = parse_line("(1.000000) can0 710#0", 9);
  ASSERT_TRUE(bad.error);
  EXPECT_FALSE(bad.error->unsupported);
}

TEST(CandumpLineReader, SkipsBadLinesCollectsErrorsAndReadsTheRest) {
  std::istringstream in(
      "(1763700000.000001) can0 710#01\n"
      "# comment\n"
      "(1763700000.000002) can0 710#0\n"  // line 3: odd digits
      "\n"
      "(1763700000.000003) can0 711#0203\n"
      "(1763700000.000004) can0 712##100\n"  // line 6: CAN FD
      "garbage\n"                            // line 7
      "(1763700000.000005) can0 713#04");    // no final newline
  candump::LineReader reader(in);
  std::vector<std::size_t> seen_by_handler;
  reader.on_error([&](const candump::ParseError& e) { seen_by_handler.push_back(e.line); });
  std::vector<uint32_t> ids;
  while (auto rec = reader.next()) ids.push_back(rec->frame.id);
  EXPECT_EQ(ids, (std::vector<uint32_t>{0x710, 0x711, 0x713}));
  ASSERT_EQ(reader.errors().size(), 3U);
  EXPECT_EQ(reader.errors()[0].line, 3U);
  EXPECT_NE(reader.errors()[0].message.find("odd number of hex digits"), std::string::npos);
  EXPECT_EQ(reader.errors()[1].line, 6U);
  EXPECT_TRUE(reader.errors()[1].unsupported);
  EXPECT_EQ(reader.errors()[2].line, 7U);
  EXPECT_EQ(reader.errors()[2].message.rfind("line 7, column 1: ", 0), 0U);
  EXPECT_EQ(seen_by_handler, (std::vector<std::size_t>{3, 6, 7}));
  EXPECT_EQ(reader.error_count(), 3U);
  EXPECT_EQ(reader.line_number(), 8U);
}

TEST(CandumpLineReader, OverlongLineIsReportedNotBuffered) {
  std::string text = "(1.000000) can0 710#" + std::string(candump::kMaxLineLength * 3, '0') + "\n";
  text += "(2.000000) can0 711#01\n";
  std::istringstream in(text);
  candump::LineReader reader(in);
  const auto rec = reader.next();
  ASSERT_TRUE(rec);
  EXPECT_EQ(rec->frame.id, 0x711U);
  ASSERT_EQ(reader.errors().size(), 1U);
  EXPECT_EQ(reader.errors()[0].message, "line 1: line longer than 4096 characters");
}

TEST(CandumpLineReader, KeepsOnlyBoundedErrorsButCountsAll) {
  std::string text;
  for (int i = 0; i < 50; ++i) text += "bad\n";
  std::istringstream in(text);
  candump::LineReader reader(in, /*max_errors_kept=*/5);
  EXPECT_FALSE(reader.next());
  EXPECT_EQ(reader.errors().size(), 5U);
  EXPECT_EQ(reader.error_count(), 50U);
}

TEST(ErrorFrame, MapsControllerStatesAndBusOff) {
  const uint8_t none[8] = {};
  auto info = interpret_error_frame(0x040, none);  // CAN_ERR_BUSOFF
  EXPECT_EQ(info.state, ControllerState::kBusOff);
  EXPECT_EQ(info.description, "bus-off");

  const uint8_t passive[8] = {0, 0x20, 0, 0, 0, 0, 0, 0};  // TX_PASSIVE
  info = interpret_error_frame(0x004, passive);
  EXPECT_EQ(info.state, ControllerState::kErrorPassive);
  EXPECT_EQ(info.description, "controller: tx error-passive");

  const uint8_t warning[8] = {0, 0x04, 0, 0, 0, 0, 0, 0};  // RX_WARNING
  EXPECT_EQ(interpret_error_frame(0x004, warning).state, ControllerState::kErrorWarning);

  const uint8_t active[8] = {0, 0x40, 0, 0, 0, 0, 0, 0};  // back to error-active
  EXPECT_EQ(interpret_error_frame(0x004, active).state, ControllerState::kUp);
  EXPECT_EQ(interpret_error_frame(0x100, none).state, ControllerState::kUp);  // restarted

  // Bus-off wins over everything else in the same frame.
  EXPECT_EQ(interpret_error_frame(0x004 | 0x040 | 0x100, passive).state, ControllerState::kBusOff);

  // No state change for a missing ACK, but a description with the counters.
  const uint8_t counters[8] = {0, 0, 0, 0, 0, 0, 96, 12};
  info = interpret_error_frame(0x020 | 0x200, counters);
  EXPECT_FALSE(info.state);
  EXPECT_EQ(info.description, "no ACK on transmission, tec=96 rec=12");
}

}  // namespace
}  // namespace fleetgw::can
