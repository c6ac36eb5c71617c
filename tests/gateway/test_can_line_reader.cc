// candump::LineReader reading in blocks: lines cut by a block boundary, the canonical-line fast
// path agreeing with the general parser's rules, and a live stream read as data arrives.
#include <sstream>
#include <streambuf>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "gateway/can/candump.h"

namespace fleetgw::can {
namespace {

using motinova::Micros;

// Every record of a long log comes back, in order, whatever block its line straddles.
TEST(CandumpBlockReader, LinesAcrossBlockBoundariesAllComeBack) {
  std::string text;
  std::vector<candump::LogRecord> expected;
  for (uint32_t i = 0; i < 60'000; ++i) {
    candump::LogRecord r;
    r.timestamp = Micros{1'763'700'000'000'000 + i * 137};
    r.interface = i % 3 == 0 ? "can0" : "vcan12";
    r.frame.id = 0x700 + i % 0x100;
    r.frame.len = static_cast<uint8_t>(i % 9);
    for (uint8_t k = 0; k < r.frame.len; ++k) r.frame.data[k] = static_cast<uint8_t>(i * 7 + k);
    text += candump::format_record(r) + (i % 5 == 0 ? "\r\n" : "\n");
    expected.push_back(r);
  }
  std::istringstream in(text);
  candump::LineReader reader(in);
  std::size_t n = 0;
  while (auto rec = reader.next()) {
    ASSERT_LT(n, expected.size());
    ASSERT_EQ(*rec, expected[n]) << "record " << n;
    ++n;
  }
  EXPECT_EQ(n, expected.size());
  EXPECT_EQ(reader.error_count(), 0U);
  EXPECT_EQ(reader.line_number(), expected.size());
}

// Lines the fast path does not take (lower case, tabs, direction token, nanoseconds, cansend
// separators) still parse as before; errors still name line and column.
TEST(CandumpBlockReader, NonCanonicalLinesParseLikeBefore) {
  std::istringstream in(
      "(1763700000.000001) can0 710#0a0b\n"
      "  (1763700000.000002)\tcan0\t711#01 R\n"
      "(1763700000.000003123) can0 712#11.22\n"
      "(1763700000.000004) can0 7ff#\n"
      "(1763700000.000005) can0 800#01\n"  // line 5: above 0x7FF
      "(1763700000.000006) can0 713#0G\n"  // line 6: bad hex
      "(1763700000.000007) can0 18FEF100#01\n");
  candump::LineReader reader(in);
  std::vector<candump::LogRecord> got;
  while (auto rec = reader.next()) got.push_back(*rec);
  ASSERT_EQ(got.size(), 5U);
  EXPECT_EQ(got[0].frame.data[0], 0x0A);
  EXPECT_EQ(got[0].frame.data[1], 0x0B);
  EXPECT_EQ(got[1].frame.id, 0x711U);
  EXPECT_EQ(got[2].timestamp, Micros{1'763'700'000'000'003});
  EXPECT_EQ(got[2].frame.len, 2);
  EXPECT_EQ(got[3].frame.id, 0x7FFU);
  EXPECT_EQ(got[3].frame.len, 0);
  EXPECT_TRUE(got[4].extended);
  ASSERT_EQ(reader.errors().size(), 2U);
  EXPECT_EQ(reader.errors()[0].message, "line 5, column 26: standard CAN ID 0x800 exceeds 0x7FF");
  EXPECT_EQ(reader.errors()[1].message, "line 6, column 31: invalid character 'G' in payload");
}

// A stream that hands out one chunk per underflow, like a pipe from `candump -L can0`.
class ChunkedBuf : public std::streambuf {
 public:
  explicit ChunkedBuf(std::vector<std::string> chunks) : chunks_(std::move(chunks)) {}
  std::size_t chunks_taken() const { return next_; }

 protected:
  int_type underflow() override {
    if (next_ == chunks_.size()) return traits_type::eof();
    std::string& c = chunks_[next_++];
    setg(c.data(), c.data(), c.data() + c.size());
    return traits_type::to_int_type(c.front());
  }

 private:
  std::vector<std::string> chunks_;
  std::size_t next_ = 0;
};

TEST(CandumpBlockReader, LiveStreamIsReadAsDataArrives) {
  ChunkedBuf buf(
      {"(1.000000) can0 710#01\n(2.0000", "00) can0 711#02\n", "(3.000000) can0 712#03"});
  std::istream in(&buf);
  candump::LineReader reader(in);
  auto first = reader.next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->frame.id, 0x710U);
  EXPECT_EQ(buf.chunks_taken(), 1U);  // did not wait for more input than the first line needs
  auto second = reader.next();
  ASSERT_TRUE(second);
  EXPECT_EQ(second->frame.id, 0x711U);
  EXPECT_EQ(second->timestamp, Micros{2'000'000});
  EXPECT_EQ(buf.chunks_taken(), 2U);
  auto third = reader.next();
  ASSERT_TRUE(third);
  EXPECT_EQ(third->frame.id, 0x712U);
  EXPECT_FALSE(reader.next());
}

}  // namespace
}  // namespace fleetgw::can
