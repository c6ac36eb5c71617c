// The real-time side: SimTransport on an io_context, run_sim with an injected transport and in
// record mode.

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <functional>
#include <optional>
#include <thread>

#include <asio/io_context.hpp>
#include <asio/post.hpp>
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

// Counts the event loop's turns that delivered frames: a handler posted by the first frame of a
// turn runs once the driver's wake-up returned (exact under any load, unlike gaps in wall time).
class TurnCounter {
 public:
  explicit TurnCounter(asio::io_context& io) : io_(io) {}
  void on_frame() {
    if (in_turn_) return;
    in_turn_ = true;
    ++turns;
    asio::post(io_, [this] { in_turn_ = false; });
  }
  int turns = 0;

 private:
  asio::io_context& io_;
  bool in_turn_ = false;
};

// Runs `io` until the transport was stopped (by a handler, once it saw what it waited for),
// failing (and stopping) after `limit` of wall time: a safety net for a broken transport, not a
// timing goal.
void run_with_limit(asio::io_context& io, SimTransport& transport,
                    std::chrono::seconds limit = std::chrono::seconds(60)) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  asio::steady_timer guard(io);
  std::function<void()> check = [&] {
    guard.expires_after(std::chrono::milliseconds(10));
    guard.async_wait([&](const std::error_code& ec) {
      if (ec || transport.health().state == can::ControllerState::kDown) return;
      if (std::chrono::steady_clock::now() >= deadline) {
        ADD_FAILURE() << "the transport did not get there within " << limit.count() << " s";
        transport.stop();
        return;
      }
      check();
    });
  };
  check();
  io.run();
}

// The gateway asks the BMS for its pack statistics at 10 s of bus time and the answer comes
// a bus instant later, with monotonic virtual timestamps, on the default (wall-clock) pacing
// and in lock-step. The request goes out from the frame handler, at a bus time the gateway
// really reached, as the node does.
void deliver_and_answer(bool lockstep) {
  asio::io_context io;
  const Scenario s = bundled("parked");
  SimTransport transport(io, s, /*acceleration=*/100.0);
  transport.set_lockstep(lockstep);
  Probe probe;
  std::vector<can::ControllerState> health;
  Micros last_ts{0};
  bool monotonic = true;
  std::optional<Micros> asked;
  transport.start(
      [&](const motinova::CanFrame& f, Micros ts) {
        monotonic = monotonic && ts >= last_ts;
        last_ts = ts;
        probe.push(f, ts);
        if (!asked && ts >= s.start + seconds(10)) {
          // The bus time the gateway has reached: the frame's (on the wall-clock pacing of a
          // loaded machine virtual_now() runs ahead of the frames delivered).
          asked = ts;
          for (const auto& can : motinova::segment(testing::ScriptedGateway::read(0x762, 0x54))) {
            EXPECT_TRUE(transport.send(can));
          }
        }
        if (asked && probe.first(0x725, 0x50, *asked) != nullptr) transport.stop();
      },
      [&](const can::BusHealth& h) { health.push_back(h.state); });
  ASSERT_EQ(health.size(), 1u);
  EXPECT_EQ(health[0], can::ControllerState::kUp);
  run_with_limit(io, transport);

  EXPECT_TRUE(monotonic);
  EXPECT_TRUE(probe.errors.empty());
  EXPECT_GT(probe.messages.size(), 50u);
  EXPECT_GE(probe.messages.front().ts, s.start);
  ASSERT_TRUE(asked.has_value());
  const auto* stats = probe.first(0x725, 0x50, *asked);
  // rx_errors: the bike's reassembler dropped the request (its two segments reached it too far
  // apart in bus time).
  ASSERT_NE(stats, nullptr) << "bike rx_errors " << transport.bike().stats().rx_errors
                            << ", frames from the gateway "
                            << transport.bike().stats().external_frames;
  if (lockstep) {
    // In lock-step the request reached the bike at the bus time it was sent, on any machine.
    EXPECT_LT(stats->ts - *asked, seconds(0.1));
  }
  EXPECT_EQ(transport.health().state, can::ControllerState::kDown);
  EXPECT_EQ(transport.health().tx_frames, 2u);
  EXPECT_EQ(transport.health().rx_frames, probe.can_frames);
  EXPECT_FALSE(transport.send(motinova::CanFrame{}));  // stopped
}

TEST(SimTransport, DeliversVirtualTimestampsAndAnswersRequests) {
  deliver_and_answer(false);
}

TEST(SimTransport, LockstepDeliversVirtualTimestampsAndAnswersRequests) {
  deliver_and_answer(true);
}

// Lock-step holds on a machine that stalls: the event loop is blocked for 300 ms of wall time
// (30 s of bus time at x100) right after the gateway sent a request. The gateway never reads a
// bus time past a frame it has not been given, and the bike hears the request at the bus time
// it was sent, so its answer comes as soon as on an idle machine. On the wall-clock pacing the
// same stall makes the bus "fall behind" by 30 s (the failure this mode exists for).
TEST(SimTransport, LockstepBusNeverRunsAheadOfTheGatewayWhenTheMachineStalls) {
  asio::io_context io;
  const Scenario s = bundled("parked");
  SimTransport transport(io, s, /*acceleration=*/100.0);
  transport.set_lockstep(true);
  Probe probe;
  Micros last_ts{0};
  std::optional<Micros> asked;
  std::optional<Micros> after_stall;
  bool ahead = false;  // virtual_now() read before a frame stamped earlier had arrived
  Micros seen_now{0};
  transport.start(
      [&](const motinova::CanFrame& f, Micros ts) {
        ahead = ahead || ts < seen_now;
        last_ts = ts;
        probe.push(f, ts);
        seen_now = std::max(seen_now, transport.virtual_now());
        if (!asked && ts >= s.start + seconds(5)) {
          asked = transport.virtual_now();
          for (const auto& can : motinova::segment(testing::ScriptedGateway::read(0x762, 0x54))) {
            transport.send(can);
          }
          // A loaded machine: this process gets no CPU for 300 ms (the stall is the point).
          std::this_thread::sleep_for(std::chrono::milliseconds(300));
          after_stall = transport.virtual_now();
        }
        if (asked && probe.first(0x725, 0x50, *asked) != nullptr) transport.stop();
      },
      nullptr);
  run_with_limit(io, transport);

  ASSERT_TRUE(asked.has_value());
  ASSERT_TRUE(after_stall.has_value());
  EXPECT_FALSE(ahead) << "the gateway read a bus time past a frame not yet delivered";
  EXPECT_EQ(*after_stall, *asked) << "the bus moved while the gateway's frames were in flight";
  const auto* stats = probe.first(0x725, 0x50, *asked);
  ASSERT_NE(stats, nullptr);
  EXPECT_LT(stats->ts - *asked, seconds(0.1)) << "the answer fell behind the stall";
}

// Coalescing: with a batch window the bike's traffic arrives in few wake-ups, every frame in
// order with its own timestamp; flush() delivers what is due at once; low latency turns
// batching off.
TEST(SimTransport, BatchWindowCoalescesWakeUpsAndFlushDeliversWhatIsDue) {
  asio::io_context io;
  const Scenario s = bundled("ride");
  SimTransport transport(io, s, /*acceleration=*/10.0);
  transport.set_batch_window(std::chrono::milliseconds(100));
  Probe probe;
  Micros last_ts{0};
  bool monotonic = true;
  TurnCounter deliveries(io);
  transport.start(
      [&](const motinova::CanFrame& f, Micros ts) {
        monotonic = monotonic && ts >= last_ts;
        last_ts = ts;
        probe.push(f, ts);
        deliveries.on_frame();
      },
      nullptr);
  asio::steady_timer check(io);
  Micros flushed_at{0};
  Micros last_before_flush{0};
  int turns_before_flush = 0;
  check.expires_after(std::chrono::milliseconds(650));
  check.async_wait([&](const std::error_code&) {
    last_before_flush = last_ts;
    turns_before_flush = deliveries.turns;
    flushed_at = transport.virtual_now();
    transport.flush();
    transport.stop();
  });
  io.run();

  EXPECT_TRUE(monotonic);
  EXPECT_TRUE(probe.errors.empty());
  // At least 6.5 s of a ride at x10 (more if the timer came late) is over a hundred messages,
  // in about one wake-up per 100 ms of wall time: bounded by the bus time covered.
  EXPECT_GT(probe.messages.size(), 100u);
  const double windows = static_cast<double>((flushed_at - s.start).count()) / 1e6 / 10 / 0.1;
  EXPECT_LE(turns_before_flush, windows + 2) << "one wake-up per 100 ms window, not per message";
  EXPECT_GE(turns_before_flush, 3);
  // flush() delivered what was due by then: nothing older than the window is left behind.
  EXPECT_GE(last_ts, last_before_flush);
  EXPECT_LE(last_ts, flushed_at);
}

TEST(SimTransport, LowLatencyDeliversEachBikeEventAtOnce) {
  asio::io_context io;
  const Scenario s = bundled("ride");
  SimTransport transport(io, s, /*acceleration=*/10.0);
  transport.set_batch_window(std::chrono::seconds(1));
  transport.set_low_latency(true);
  TurnCounter deliveries(io);
  const auto started = std::chrono::steady_clock::now();
  transport.start(
      [&](const motinova::CanFrame&, Micros ts) {
        deliveries.on_frame();
        if (ts >= s.start + seconds(4)) transport.stop();
      },
      nullptr);
  run_with_limit(io, transport);
  // Batched, the bike's traffic would wake the loop at most once per 1 s window (however slow
  // the machine made the run); per event it wakes it whenever an event is due.
  const double windows =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  EXPECT_GT(deliveries.turns, windows + 2) << "events are held back for the window";
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
  EXPECT_EQ(run_sim(o), 0);
  EXPECT_EQ(spec_seen, "fake:bus");
  EXPECT_GT(frames.size(), 300u);
  // It stopped at the duration's bus time, not later: no more frames than the bike puts on
  // the bus in 20 s.
  Bike bike(load_scenario(o.scenario));
  std::size_t in_duration = 0;
  bike.advance_to(bike.scenario().start + seconds(20),
                  [&](const motinova::CanFrame&) { ++in_duration; });
  EXPECT_LE(frames.size(), in_duration);
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
