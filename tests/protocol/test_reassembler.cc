// Reassembly of application frames from CAN segments, and its behaviour on bad input.
#include <gtest/gtest.h>

#include <random>

#include "motinova/crc32.h"
#include "motinova/frame.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"
#include "test_util.h"

namespace motinova {
namespace {

using test::can_frame;
using test::hex;
using test::RecordingSink;

constexpr Micros ms(int64_t v) {
  return Micros(v * 1000);
}

const char* kT2 = "55 AA 16 08 83 06 55 4E 4C 4F 43 4B 84 0B 4B 96 F0";        // 0x767 UNLOCK
const char* kT7 = "55 AA 0C 0A 10 08 53 48 55 54 44 4F 57 4E F8 FF C9 A0 F0";  // 0x760

std::vector<CanFrame> segs(uint16_t id, const char* frame) {
  return segment(id, hex(frame));
}

void push_all(Reassembler& r, const std::vector<CanFrame>& frames, RecordingSink& sink,
              Micros start = ms(0), Micros step = ms(1)) {
  Micros t = start;
  for (const auto& f : frames) {
    r.push(f, t, sink);
    t += step;
  }
}

void expect_error_counts_match(const Reassembler& r, const RecordingSink& sink) {
  EXPECT_EQ(r.stats().total_errors(), sink.errors.size());
  for (std::size_t k = 0; k < kReassemblyErrorKinds; ++k) {
    const auto kind = static_cast<ReassemblyError>(k);
    const auto n = std::count_if(sink.errors.begin(), sink.errors.end(),
                                 [kind](const auto& e) { return e.kind == kind; });
    EXPECT_EQ(r.stats().error(kind), static_cast<uint64_t>(n)) << reassembly_error_name(kind);
  }
}

TEST(Reassembler, ReassemblesSpecVector) {
  Reassembler r;
  RecordingSink sink;
  push_all(r, segs(0x767, kT2), sink);
  ASSERT_EQ(sink.frames.size(), 1u);
  EXPECT_EQ(sink.frames[0].command(), 0x8306);
  EXPECT_EQ(std::string(sink.frames[0].data.begin(), sink.frames[0].data.end()), "UNLOCK");
  EXPECT_TRUE(sink.errors.empty());
  EXPECT_EQ(r.stats().frames_ok, 1u);
  EXPECT_EQ(r.stats().crc_big_endian, 1u);
}

TEST(Reassembler, InterleavedIdsDoNotDisturbEachOther) {
  Reassembler r;
  RecordingSink sink;
  const auto a = segs(0x767, kT2);
  const auto b = segs(0x760, kT7);
  for (std::size_t i = 0; i < 3; ++i) {
    r.push(a[i], ms(i), sink);
    r.push(b[i], ms(i), sink);
  }
  ASSERT_EQ(sink.frames.size(), 2u);
  EXPECT_EQ(sink.frames[0].can_id, 0x767);
  EXPECT_EQ(sink.frames[1].can_id, 0x760);
  EXPECT_TRUE(sink.errors.empty());
}

TEST(Reassembler, PaddedLastSegmentIsAccepted) {
  Reassembler r;
  RecordingSink sink;
  auto s = segs(0x767, kT2);
  s.back().len = 8;  // sender pads the last frame to DLC 8 (U15)
  s.back().data = {0xF0, 0, 0, 0, 0, 0, 0, 0};
  push_all(r, s, sink);
  EXPECT_EQ(sink.frames.size(), 1u);
  EXPECT_TRUE(sink.errors.empty());
}

TEST(Reassembler, GapTimeoutDropsPartialMessage) {
  Reassembler r;  // default gap 100 ms
  RecordingSink sink;
  const auto s = segs(0x767, kT2);
  r.push(s[0], ms(0), sink);
  r.push(s[1], ms(50), sink);
  r.push(s[2], ms(200), sink);  // too late: the partial is abandoned, this segment is orphaned
  EXPECT_TRUE(sink.frames.empty());
  ASSERT_EQ(sink.errors.size(), 2u);
  EXPECT_EQ(sink.errors[0].kind, ReassemblyError::kGapTimeout);
  EXPECT_EQ(sink.errors[0].bytes_dropped, 16);
  EXPECT_EQ(sink.errors[1].kind, ReassemblyError::kBadHeader);
  // The next complete message is received normally.
  push_all(r, s, sink, ms(300));
  EXPECT_EQ(sink.frames.size(), 1u);
  expect_error_counts_match(r, sink);
}

TEST(Reassembler, GapTimeoutIsConfigurable) {
  Reassembler r(ReassemblerOptions{.gap_timeout = ms(500)});
  RecordingSink sink;
  push_all(r, segs(0x767, kT2), sink, ms(0), ms(300));
  EXPECT_EQ(sink.frames.size(), 1u);
}

TEST(Reassembler, ExpireFlushesStalePartials) {
  Reassembler r;
  RecordingSink sink;
  r.push(segs(0x767, kT2)[0], ms(0), sink);
  r.expire(ms(50), sink);
  EXPECT_TRUE(sink.errors.empty());
  r.expire(ms(150), sink);
  ASSERT_EQ(sink.errors.size(), 1u);
  EXPECT_EQ(sink.errors[0].kind, ReassemblyError::kGapTimeout);
  EXPECT_EQ(sink.errors[0].can_id, 0x767u);
}

TEST(Reassembler, RestartMidWayKeepsTheNewMessage) {
  Reassembler r;
  RecordingSink sink;
  const auto t7 = segs(0x760, kT7);
  r.push(t7[0], ms(0), sink);
  r.push(t7[1], ms(1), sink);
  push_all(r, t7, sink, ms(2));  // sender restarts the message before finishing it
  ASSERT_EQ(sink.frames.size(), 1u);
  ASSERT_EQ(sink.errors.size(), 1u);
  EXPECT_EQ(sink.errors[0].kind, ReassemblyError::kRestarted);
  EXPECT_EQ(sink.errors[0].bytes_dropped, 16);
}

TEST(Reassembler, DataSegmentStartingWith55AaIsContinued) {
  // A 16-byte payload whose second segment begins with 55 AA but is not a plausible header.
  AppFrame f = make_frame(0x720, Mode::kReport, 0x14,
                          hex("00 01 55 AA 77 01 02 03 04 05 06 07 08 09 0A 0B"));
  auto s = segment(f);
  ASSERT_EQ(s[1].data[0], 0x55);
  ASSERT_EQ(s[1].data[1], 0xAA);
  Reassembler r;
  RecordingSink sink;
  push_all(r, s, sink);
  ASSERT_EQ(sink.frames.size(), 1u);
  EXPECT_EQ(sink.frames[0], f);
}

// Issue 11 item 10: a BMS status with a charge current of +21.930 A (s16 0x55AA) puts 55 AA at
// the start of its second segment, followed by bytes that look like a header. It must decode.
TEST(Reassembler, HeaderLikeSegmentInsideAMessageDoesNotLoseIt) {
  Reassembler r;
  RecordingSink sink;
  push_all(
      r,
      {can_frame(0x720, "55 AA 0C 12 10 10 C3 50"), can_frame(0x720, "55 AA 0C 10 10 0E 41 4B"),
       can_frame(0x720, "01 62 01 41 00 2A 0A 49"), can_frame(0x720, "AB 2C F0")},
      sink);
  ASSERT_EQ(sink.frames.size(), 1u);
  EXPECT_EQ(sink.frames[0].command(), 0x1010);
  EXPECT_EQ(sink.frames[0].data[2], 0x55);
  EXPECT_EQ(sink.frames[0].data[3], 0xAA);
  EXPECT_TRUE(sink.errors.empty());
  // Nothing is left open: the next message on the ID is received normally.
  push_all(r, segment(make_frame(0x720, Mode::kReport, 0x13, "SHUTDOWN")), sink, ms(10));
  ASSERT_EQ(sink.frames.size(), 2u);
  EXPECT_EQ(sink.frames[1].command(), 0x1308);
  EXPECT_TRUE(sink.errors.empty());
}

// Property (issue 11): any valid message whose bytes contain 55 AA followed by a plausible header
// at any segment boundary (one or several), interleaved segment by segment with other IDs,
// decodes exactly once and without errors.
TEST(Reassembler, HeaderLikeBytesAtAnySegmentBoundaryNeverLoseTheMessage) {
  std::mt19937_64 rng(20261123);
  for (int trial = 0; trial < 3000; ++trial) {
    const std::size_t n = 12 + rng() % 230;  // frame of n + 11 bytes: 3..31 segments
    std::vector<uint8_t> data(n);
    for (auto& b : data) b = static_cast<uint8_t>(rng());
    // Frame offset of data[k] is 6 + k. Plant header-like bytes at some segment boundaries.
    const uint8_t modes[] = {0x0C, 0x11, 0x16};
    for (std::size_t boundary = 8; boundary + 8 <= 6 + n; boundary += 8) {
      if (rng() % 3 != 0 && boundary != 8) continue;
      const std::size_t k = boundary - 6;
      const uint8_t length = static_cast<uint8_t>(2 + rng() % 254);
      const uint8_t fake[6] = {0x55,
                               0xAA,
                               modes[rng() % 3],
                               length,
                               static_cast<uint8_t>(rng()),
                               static_cast<uint8_t>(length - 2)};
      for (std::size_t j = 0; j < 6 && k + j < n; ++j) data[k + j] = fake[j];
    }
    const uint16_t id = static_cast<uint16_t>(0x700 | (rng() & 0xFF));
    const AppFrame f = make_frame(id, Mode::kReport, static_cast<uint8_t>(rng()), data);
    const auto mine = segment(f);
    // Other IDs interleaved: a complete valid message and random garbage.
    const uint16_t other_id = static_cast<uint16_t>(id ^ 0x01);
    const auto other = segment(make_frame(other_id, Mode::kReport, 0x10, data));
    Reassembler r(ReassemblerOptions{.crc_order = CrcOrder::kAuto});
    RecordingSink sink;
    Micros t{0};
    for (std::size_t i = 0; i < std::max(mine.size(), other.size()); ++i) {
      if (i < mine.size()) r.push(mine[i], t += ms(1), sink);
      if (i < other.size()) r.push(other[i], t += ms(1), sink);
    }
    ASSERT_EQ(sink.frames.size(), 2u) << "trial " << trial << " n " << n;
    EXPECT_TRUE(sink.frames[0] == f || sink.frames[1] == f) << "trial " << trial;
    EXPECT_TRUE(sink.errors.empty()) << "trial " << trial;
  }
}

// A sender that restarts twice mid-way, each time with a header-like abandoned prefix: only the
// complete message comes out, the abandoned attempts are reported once each.
TEST(Reassembler, RepeatedRestartsKeepOnlyTheCompleteMessage) {
  Reassembler r;
  RecordingSink sink;
  const auto t7 = segs(0x760, kT7);
  r.push(t7[0], ms(0), sink);
  r.push(t7[1], ms(1), sink);
  r.push(t7[0], ms(2), sink);
  push_all(r, t7, sink, ms(3));
  ASSERT_EQ(sink.frames.size(), 1u);
  EXPECT_EQ(sink.frames[0].command(), 0x1008);
  EXPECT_GE(r.stats().error(ReassemblyError::kRestarted), 1u);
  expect_error_counts_match(r, sink);
}

TEST(Reassembler, TruncatedMessageIsReported) {
  Reassembler r;
  RecordingSink sink;
  const auto s = segs(0x760, kT7);
  r.push(s[0], ms(0), sink);
  CanFrame short_seg = s[1];
  short_seg.len = 5;  // a short segment can only be the last one: the message is truncated
  r.push(short_seg, ms(1), sink);
  EXPECT_TRUE(sink.frames.empty());
  ASSERT_EQ(sink.errors.size(), 1u);
  EXPECT_EQ(sink.errors[0].kind, ReassemblyError::kTruncated);
}

TEST(Reassembler, EachStructuralErrorHasItsKind) {
  struct Case {
    const char* frame;
    ReassemblyError kind;
  };
  const Case cases[] = {
      {"55 AA 12 03 22 01 00 01 29 51 22 F0", ReassemblyError::kBadMode},
      {"55 AA 11 01 22 01 00 01 29 51 22 F0", ReassemblyError::kBadLength},
      {"55 AA 11 03 22 02 00 01 29 51 22 F0", ReassemblyError::kLengthMismatch},
      {"55 AA 11 03 22 01 00 01 29 51 22 F1", ReassemblyError::kBadTail},
      {"55 AA 11 03 22 01 01 01 29 51 22 F0", ReassemblyError::kBadCrc},
      {"54 AA 11 03 22 01 00 01 29 51 22 F0", ReassemblyError::kBadHeader},
  };
  for (const auto& c : cases) {
    Reassembler r;
    RecordingSink sink;
    const auto s = segs(0x712, c.frame);
    push_all(r, s, sink);
    r.expire(ms(1000), sink);
    EXPECT_TRUE(sink.frames.empty()) << c.frame;
    ASSERT_FALSE(sink.errors.empty()) << c.frame;
    EXPECT_EQ(sink.errors[0].kind, c.kind) << c.frame;
    expect_error_counts_match(r, sink);
  }
}

TEST(Reassembler, ForeignIdsAreIgnoredAndCounted) {
  Reassembler r;
  RecordingSink sink;
  for (const auto& f : segs(0x767, kT2)) {
    CanFrame foreign = f;
    foreign.id = 0x123;
    r.push(foreign, ms(0), sink);
  }
  EXPECT_TRUE(sink.frames.empty());
  EXPECT_EQ(r.stats().error(ReassemblyError::kForeignId), 3u);
}

TEST(Reassembler, GarbageBetweenFramesDoesNotHideThem) {
  Reassembler r;
  RecordingSink sink;
  Micros t{0};
  for (int i = 0; i < 3; ++i) {
    r.push(can_frame(0x767, "DE AD BE EF 01 02 03 04"), t, sink);
    for (const auto& f : segs(0x767, kT2)) r.push(f, t += ms(1), sink);
  }
  EXPECT_EQ(sink.frames.size(), 3u);
  EXPECT_EQ(r.stats().error(ReassemblyError::kBadHeader), 3u);
}

TEST(Reassembler, CrcOrderAutoReportsWhichOrderMatched) {
  Reassembler r(ReassemblerOptions{.crc_order = CrcOrder::kAuto});
  RecordingSink sink;
  push_all(r, segs(0x767, kT2), sink);
  push_all(r, segs(0x712, "55 AA 11 03 22 01 00 22 51 29 01 F0"), sink, ms(10));
  EXPECT_EQ(sink.frames.size(), 2u);
  EXPECT_EQ(r.stats().crc_big_endian, 1u);
  EXPECT_EQ(r.stats().crc_little_endian, 1u);
}

TEST(Reassembler, StrictCrcOrderRejectsTheOther) {
  Reassembler r(ReassemblerOptions{.crc_order = CrcOrder::kLittle});
  RecordingSink sink;
  push_all(r, segs(0x767, kT2), sink);
  EXPECT_TRUE(sink.frames.empty());
  EXPECT_EQ(r.stats().error(ReassemblyError::kBadCrc), 1u);
}

// Every single-bit flip anywhere in a multi-segment message must be caught: the CRC detects all
// single-bit errors, and structural bits are checked before it.
TEST(Reassembler, EveryBitFlipIsRejected) {
  const auto frame_bytes = hex(kT7);
  for (std::size_t byte = 0; byte < frame_bytes.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      auto corrupted = frame_bytes;
      corrupted[byte] ^= static_cast<uint8_t>(1u << bit);
      Reassembler r;
      RecordingSink sink;
      push_all(r, segment(0x760, corrupted), sink);
      r.expire(ms(10'000), sink);
      EXPECT_TRUE(sink.frames.empty()) << "byte " << byte << " bit " << bit;
      EXPECT_FALSE(sink.errors.empty()) << "byte " << byte << " bit " << bit;
      expect_error_counts_match(r, sink);
    }
  }
}

// 10,000 random CAN frames on random MOTINOVA IDs, with and without valid headers: nothing
// crashes, no frame is reported unless its CRC is genuinely valid, and every error is counted.
TEST(Reassembler, RandomFramesNeverYieldFalseMessages) {
  std::mt19937_64 rng(1234);
  Reassembler r;
  RecordingSink sink;
  for (int i = 0; i < 10'000; ++i) {
    CanFrame f;
    f.id = 0x700 | static_cast<uint32_t>(rng() & 0xFF);
    f.len = static_cast<uint8_t>(rng() % 9);
    for (auto& b : f.data) b = static_cast<uint8_t>(rng());
    if (rng() % 4 == 0 && f.len >= 2) {
      f.data[0] = 0x55;
      f.data[1] = 0xAA;
    }
    r.push(f, Micros(i * 100), sink);
  }
  r.expire(Micros(10'000'000'000), sink);
  for (const auto& f : sink.frames) {
    const auto bytes = encode_frame(f);
    EXPECT_TRUE(parse_frame(f.can_id, bytes.span(), CrcOrder::kBig).ok());
  }
  EXPECT_EQ(r.stats().can_frames, 10'000u);
  EXPECT_GT(r.stats().total_errors(), 1'000u);
  expect_error_counts_match(r, sink);
}

}  // namespace
}  // namespace motinova
