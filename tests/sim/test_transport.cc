// The real-time side: SimTransport on an io_context, run_sim with an injected transport and in
// record mode.

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>

#include "gateway/can/candump.h"
#include "gateway/sim/sim_command.h"
#include "gateway/sim/sim_transport.h"
#include "sim_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::sim {
namespace {

using testing::bundled;
using testing::Probe;
using testing::seconds;

TEST(SimTransport, DeliversVirtualTimestampsAndAnswersRequests) {
  asio::io_context io;
  const Scenario s = bundled("parked");
  SimTransport transport(io, s, /*acceleration=*/100.0);
  Probe probe;
  std::vector<can::ControllerState> health;
  Micros last_ts{0};
  bool monotonic = true;
  transport.start(
      [&](const motinova::CanFrame& f, Micros ts) {
        monotonic = monotonic && ts >= last_ts;
        last_ts = ts;
        probe.push(f, ts);
      },
      [&](const can::BusHealth& h) { health.push_back(h.state); });
  ASSERT_EQ(health.size(), 1u);
  EXPECT_EQ(health[0], can::ControllerState::kUp);

  // After 0.1 s real (10 s virtual) the gateway asks the BMS for its pack statistics.
  asio::steady_timer ask(io);
  Micros asked{0};
  ask.expires_after(std::chrono::milliseconds(100));
  ask.async_wait([&](const std::error_code&) {
    asked = transport.virtual_now();
    for (const auto& can : motinova::segment(testing::ScriptedGateway::read(0x762, 0x54))) {
      EXPECT_TRUE(transport.send(can));
    }
  });
  asio::steady_timer done(io);
  done.expires_after(std::chrono::milliseconds(300));
  done.async_wait([&](const std::error_code&) { transport.stop(); });
  io.run();

  EXPECT_TRUE(monotonic);
  EXPECT_TRUE(probe.errors.empty());
  EXPECT_GT(probe.messages.size(), 50u);
  EXPECT_GE(probe.messages.front().ts, s.start);
  EXPECT_LT(last_ts, s.start + seconds(60));  // ~30 s virtual at x100
  const auto* stats = probe.first(0x725, 0x50, asked);
  ASSERT_NE(stats, nullptr);
  EXPECT_LT(stats->ts - asked, seconds(1));
  EXPECT_EQ(transport.health().state, can::ControllerState::kDown);
  EXPECT_EQ(transport.health().tx_frames, 2u);
  EXPECT_EQ(transport.health().rx_frames, probe.can_frames);
  EXPECT_FALSE(transport.send(motinova::CanFrame{}));  // stopped
}

// Coalescing: with a batch window the bike's traffic arrives in few wake-ups, every frame in
// order with its own timestamp; flush() delivers what is due at once; low latency turns
// batching off.
TEST(SimTransport, BatchWindowCoalescesWakeUpsAndFlushDeliversWhatIsDue) {
  using Clock = std::chrono::steady_clock;
  asio::io_context io;
  SimTransport transport(io, bundled("ride"), /*acceleration=*/10.0);
  transport.set_batch_window(std::chrono::milliseconds(100));
  Probe probe;
  Micros last_ts{0};
  bool monotonic = true;
  std::vector<Clock::time_point> deliveries;  // one entry per wake-up that delivered frames
  transport.start(
      [&](const motinova::CanFrame& f, Micros ts) {
        monotonic = monotonic && ts >= last_ts;
        last_ts = ts;
        probe.push(f, ts);
        const auto now = Clock::now();
        if (deliveries.empty() || now - deliveries.back() > std::chrono::milliseconds(20)) {
          deliveries.push_back(now);
        }
      },
      nullptr);
  asio::steady_timer check(io);
  Micros flushed_at{0};
  Micros last_before_flush{0};
  check.expires_after(std::chrono::milliseconds(650));
  check.async_wait([&](const std::error_code&) {
    last_before_flush = last_ts;
    flushed_at = transport.virtual_now();
    transport.flush();
    transport.stop();
  });
  io.run();

  EXPECT_TRUE(monotonic);
  EXPECT_TRUE(probe.errors.empty());
  // 6.5 s of a ride at x10 is well over a hundred messages, in about 7 wake-ups.
  EXPECT_GT(probe.messages.size(), 100u);
  EXPECT_LE(deliveries.size(), 9u) << "one wake-up per 100 ms window, not per message";
  EXPECT_GE(deliveries.size(), 3u);
  // flush() delivered what was due by then: nothing older than the window is left behind.
  EXPECT_GT(last_ts, last_before_flush);
  EXPECT_LE(last_ts, flushed_at);
}

TEST(SimTransport, LowLatencyDeliversEachBikeEventAtOnce) {
  using Clock = std::chrono::steady_clock;
  asio::io_context io;
  SimTransport transport(io, bundled("ride"), /*acceleration=*/10.0);
  transport.set_batch_window(std::chrono::milliseconds(100));
  transport.set_low_latency(true);
  std::vector<Clock::time_point> deliveries;
  transport.start(
      [&](const motinova::CanFrame&, Micros) {
        const auto now = Clock::now();
        if (deliveries.empty() || now - deliveries.back() > std::chrono::milliseconds(2)) {
          deliveries.push_back(now);
        }
      },
      nullptr);
  asio::steady_timer stop(io);
  stop.expires_after(std::chrono::milliseconds(400));
  stop.async_wait([&](const std::error_code&) { transport.stop(); });
  io.run();
  EXPECT_GT(deliveries.size(), 15u) << "events are not held back for the window";
}

// Stands in for the UDP/SocketCAN transport in run_sim.
class FakeBus final : public can::Transport {
 public:
  explicit FakeBus(std::vector<motinova::CanFrame>& sink) : sink_(sink) {}
  void start(FrameHandler, HealthHandler) override { health_.state = can::ControllerState::kUp; }
  bool send(const motinova::CanFrame& f) override {
    sink_.push_back(f);
    return true;
  }
  void stop() override { health_.state = can::ControllerState::kDown; }
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "fake"; }

 private:
  std::vector<motinova::CanFrame>& sink_;
  can::BusHealth health_;
};

TEST(RunSim, RunsOnTheGivenTransportForTheDuration) {
  std::vector<motinova::CanFrame> frames;
  std::string spec_seen;
  SimCliOptions o;
  o.scenario = bundled_scenario_dir() / "demo.toml";
  o.speed = 200;
  o.duration_s = 20;  // 0.1 s of real time
  o.bus = "fake:bus";
  o.transport_factory = [&](asio::io_context&, std::string_view spec) {
    spec_seen = spec;
    return std::make_unique<FakeBus>(frames);
  };
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(run_sim(o), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  EXPECT_EQ(spec_seen, "fake:bus");
  EXPECT_GT(frames.size(), 300u);
}

TEST(RunSim, BadScenarioIsExitCode2) {
  const fleetgw::testing::TempDir dir("fleetgw-sim");
  const auto path = dir.file("fleetgw_sim_bad.toml");
  {
    std::ofstream out(path);
    out << "[bike]\nsoc_pct = 101\n";
  }
  SimCliOptions o;
  o.scenario = path;
  o.record = dir.file("fleetgw_sim_unused.log");
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_sim(o), 2);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("fleetgw_sim_bad.toml:2: bike.soc_pct"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(o.record)) << "nothing is recorded from a bad scenario";
}

TEST(RunSim, BadBusSpecIsExitCode2) {
  SimCliOptions o;
  o.scenario = bundled_scenario_dir() / "parked.toml";
  o.bus = "udp:notaport:1";
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_sim(o), 2);
  EXPECT_NE(::testing::internal::GetCapturedStderr().find("notaport"), std::string::npos);
}

TEST(RunSim, RecordModeWritesAReadableCandumpLog) {
  const fleetgw::testing::TempDir dir("fleetgw-sim");
  const auto path = dir.file("fleetgw_sim_record.log");
  SimCliOptions o;
  o.scenario = bundled_scenario_dir() / "demo.toml";
  o.duration_s = 30;
  o.record = path;
  ASSERT_EQ(run_sim(o), 0);
  std::ifstream in(path);
  can::candump::LineReader reader(in);
  Probe probe;
  std::size_t n = 0;
  Micros last{0};
  while (auto rec = reader.next()) {
    ++n;
    EXPECT_GE(rec->timestamp, last);
    last = rec->timestamp;
    probe.push(rec->frame, rec->timestamp);
  }
  EXPECT_EQ(reader.error_count(), 0u);
  EXPECT_GT(n, 1000u);
  EXPECT_TRUE(probe.errors.empty());
  // The demo unlocks lock 2 at 3 s: the log carries the unlocking/unlocked broadcasts.
  EXPECT_GE(probe.on(0x780, 0x10).size(), 30u);
}

}  // namespace
}  // namespace fleetgw::sim
