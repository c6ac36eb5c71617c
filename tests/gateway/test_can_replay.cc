// Replay transport: plays a candump -L file as the bus, fast and at recorded pace.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <asio/io_context.hpp>
#include <asio/post.hpp>

#include "gateway/can/candump.h"
#include "gateway/can/replay_transport.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::can {
namespace {

using motinova::CanFrame;
using motinova::Micros;
using Clock = std::chrono::steady_clock;

struct Received {
  CanFrame frame;
  Micros ts;
};

// A temporary candump file, removed again at the end of the test.
class TempFile {
 public:
  explicit TempFile(const std::string& text) : path_(dir_.file("replay.log")) {
    std::ofstream(path_) << text;
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  fleetgw::testing::TempDir dir_{"fleetgw-replay"};
  std::filesystem::path path_;
};

// The file every test plays: MOTINOVA frames mixed with what the acceptance filter drops, an
// error frame and two malformed lines.
const char* const kLog =
    "(1763700000.000000) can0 710#0102\n"
    "(1763700000.010000) can0 123#FF\n"  // outside 0x700-0x7FF: filtered
    "(1763700000.020000) can0 721#AABBCCDD\n"
    "(1763700000.030000) can0 710#0\n"                      // line 4: malformed
    "(1763700000.040000) can0 18FF0710#01\n"                // extended: filtered
    "(1763700000.050000) can0 740#R\n"                      // remote: filtered
    "(1763700000.060000) can0 20000040#0000000000000000\n"  // bus-off error frame
    "(1763700000.070000) can0 716##1001122\n"               // line 8: CAN FD, unsupported
    "(1763700000.080000) can0 7FF#0011223344556677\n";

std::vector<candump::LogRecord> expected_frames(const std::string& text) {
  std::istringstream in(text);
  candump::LineReader reader(in);
  std::vector<candump::LogRecord> out;
  while (auto r = reader.next()) {
    if (r->is_standard_data() && motinova::is_motinova_id(r->frame.id)) out.push_back(*r);
  }
  return out;
}

TEST(ReplayTransport, FastModeDeliversTheFileFramesAndTimestamps) {
  TempFile file(kLog);
  asio::io_context io;
  ReplayTransport replay(io, file.path(), ReplayOptions{});
  std::vector<Received> got;
  std::vector<BusHealth> health;
  int ends = 0;
  ReplaySummary summary;
  replay.on_end([&](const ReplaySummary& s) {
    ++ends;
    summary = s;
  });
  replay.start(
      [&](const CanFrame& f, Micros ts) {
        got.push_back({f, ts});
      },
      [&](const BusHealth& h) { health.push_back(h); });
  EXPECT_TRUE(got.empty()) << "start() must not deliver synchronously";
  io.run();

  const auto want = expected_frames(kLog);
  ASSERT_EQ(want.size(), 3U);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].frame, want[i].frame) << i;
    EXPECT_EQ(got[i].ts, want[i].timestamp) << i;
  }
  EXPECT_EQ(ends, 1);
  EXPECT_TRUE(replay.finished());
  EXPECT_EQ(summary.frames, 3U);
  EXPECT_EQ(summary.filtered, 3U);
  EXPECT_EQ(summary.error_frames, 1U);
  EXPECT_EQ(summary.malformed_lines, 2U);
  EXPECT_EQ(summary.lines, 9U);
  ASSERT_EQ(replay.errors().size(), 2U);
  EXPECT_EQ(replay.errors()[0].line, 4U);
  EXPECT_EQ(replay.errors()[1].line, 8U);

  // Health: up, bus-off from the error frame, down at the end of the file.
  ASSERT_GE(health.size(), 3U);
  EXPECT_EQ(health.front().state, ControllerState::kUp);
  EXPECT_EQ(health[1].state, ControllerState::kBusOff);
  EXPECT_EQ(health.back().state, ControllerState::kDown);
  EXPECT_NE(health.back().detail.find("end of replay"), std::string::npos);
  EXPECT_EQ(replay.health().rx_frames, 3U);
  EXPECT_EQ(replay.health().error_frames, 1U);
}

TEST(ReplayTransport, FastModeYieldsToTheLoopBetweenBatches) {
  std::string text;
  for (int i = 0; i < 1000; ++i) {
    text += candump::format_line(Micros{1'000'000 + i}, "can0", CanFrame{0x710, 1, {}}) + "\n";
  }
  TempFile file(text);
  asio::io_context io;
  ReplayOptions opt;
  opt.batch_size = 10;
  ReplayTransport replay(io, file.path(), opt);
  std::size_t delivered = 0;
  std::size_t delivered_when_other_work_ran = 0;
  replay.start([&](const CanFrame&, Micros) { ++delivered; }, nullptr);
  asio::post(io, [&] { asio::post(io, [&] { delivered_when_other_work_ran = delivered; }); });
  io.run();
  EXPECT_EQ(delivered, 1000U);
  EXPECT_GT(delivered_when_other_work_ran, 0U);
  EXPECT_LT(delivered_when_other_work_ran, 100U) << "other handlers starved during the replay";
}

TEST(ReplayTransport, RecordedPaceWithSpeedFactor) {
  // 0, 200, 400, 800 ms recorded; at speed 4 that is 0, 50, 100, 200 ms of wall time.
  const std::vector<int> offsets_ms = {0, 200, 400, 800};
  std::string text;
  for (int ms : offsets_ms) {
    text += candump::format_line(Micros{1763700000'000000LL + ms * 1000LL}, "can0",
                                 CanFrame{0x712, 2, {static_cast<uint8_t>(ms / 10), 0}}) +
            "\n";
  }
  TempFile file(text);
  asio::io_context io;
  ReplayOptions opt;
  opt.pace = ReplayOptions::Pace::kRecorded;
  opt.speed = 4.0;
  ReplayTransport replay(io, file.path(), opt);
  std::vector<Clock::duration> arrival;
  std::vector<Micros> stamps;
  const auto t0 = Clock::now();
  replay.start(
      [&](const CanFrame&, Micros ts) {
        arrival.push_back(Clock::now() - t0);
        stamps.push_back(ts);
      },
      nullptr);
  io.run();
  const auto total = Clock::now() - t0;

  ASSERT_EQ(arrival.size(), offsets_ms.size());
  for (std::size_t i = 0; i < offsets_ms.size(); ++i) {
    const auto due = std::chrono::microseconds(offsets_ms[i] * 1000 / 4);
    // Never early (1 ms slack for clock granularity): a loaded machine can only make it late.
    EXPECT_GE(arrival[i], due - std::chrono::milliseconds(1)) << "frame " << i;
    EXPECT_EQ(stamps[i], Micros{1763700000'000000LL + offsets_ms[i] * 1000LL});
  }
  // The recorded pace is itself wall time: the factor shows in the whole replay taking less
  // than the recording (800 ms) where it is due at 200 ms; how late a loaded machine delivers
  // each frame is no part of it.
  EXPECT_LT(total, std::chrono::milliseconds(800)) << "speed factor not applied";
}

TEST(ReplayTransport, CapturesSentFramesAndFiltersInterface) {
  const std::string text =
      "(1.000000) can0 710#01\n"
      "(1.000001) can1 711#02\n"
      "(1.000002) can0 712#03\n";
  asio::io_context io;
  ReplayOptions opt;
  opt.interface = "can0";
  opt.capture_sent = true;
  ReplayTransport replay(io, std::make_unique<std::istringstream>(text), "inline", opt);
  std::vector<uint32_t> ids;
  replay.start(
      [&](const CanFrame& f, Micros) {
        ids.push_back(f.id);
        EXPECT_TRUE(replay.send(CanFrame{0x760, 1, {f.data[0]}}));
      },
      nullptr);
  io.run();
  EXPECT_EQ(ids, (std::vector<uint32_t>{0x710, 0x712}));
  EXPECT_EQ(replay.summary().filtered, 1U);
  ASSERT_EQ(replay.captured().size(), 2U);
  EXPECT_EQ(replay.captured()[1], (CanFrame{0x760, 1, {0x03}}));
  EXPECT_EQ(replay.health().tx_frames, 2U);
  // After the end of the replay nothing more can be sent.
  EXPECT_FALSE(replay.send(CanFrame{0x760, 0, {}}));
  EXPECT_EQ(replay.health().tx_failures, 1U);
}

TEST(ReplayTransport, StopFromHandlerHaltsDelivery) {
  std::string text;
  for (int i = 0; i < 100; ++i) text += "(1.000000) can0 710#01\n";
  asio::io_context io;
  ReplayTransport replay(io, std::make_unique<std::istringstream>(text), "inline", {});
  int n = 0;
  bool ended = false;
  replay.on_end([&](const ReplaySummary&) { ended = true; });
  replay.start(
      [&](const CanFrame&, Micros) {
        if (++n == 5) replay.stop();
      },
      nullptr);
  io.run();
  EXPECT_EQ(n, 5);
  EXPECT_FALSE(ended);
}

TEST(ReplayTransport, DestroyedWithWorkPendingIsSafe) {
  asio::io_context io;
  {
    ReplayOptions opt;
    opt.pace = ReplayOptions::Pace::kRecorded;
    ReplayTransport replay(io,
                           std::make_unique<std::istringstream>("(1.0) can0 710#01\n"
                                                                "(9.0) can0 710#02\n"),
                           "inline", opt);
    replay.start([](const CanFrame&, Micros) {}, nullptr);
    io.run_for(std::chrono::milliseconds(20));
  }
  io.restart();
  io.run();  // pending timer/post handlers of the dead transport must not touch it
  SUCCEED();
}

TEST(ReplayTransport, BadFileAndOptionsFailClearly) {
  asio::io_context io;
  try {
    ReplayTransport replay(io, std::filesystem::path("/nonexistent/ride.log"), ReplayOptions{});
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/ride.log"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("No such file"), std::string::npos) << e.what();
  }
  ReplayOptions bad;
  bad.speed = 0;
  EXPECT_THROW(ReplayTransport(io, std::make_unique<std::istringstream>(""), "x", bad),
               std::invalid_argument);
}

TEST(ReplayTransport, EmptyFileEndsImmediately) {
  asio::io_context io;
  ReplayTransport replay(io, std::make_unique<std::istringstream>(""), "empty", {});
  int ends = 0;
  replay.on_end([&](const ReplaySummary& s) {
    ++ends;
    EXPECT_EQ(s.frames, 0U);
  });
  replay.start(nullptr, nullptr);
  io.run();
  EXPECT_EQ(ends, 1);
}

}  // namespace
}  // namespace fleetgw::can
