// Notifier and watchdog against a test NOTIFY_SOCKET: the messages systemd would receive.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <asio/post.hpp>
#include <future>
#include <thread>
#include <vector>

#include "gateway/status/notifier.h"
#include "status_test_util.h"

namespace fleetgw::status {
namespace {

using namespace std::chrono_literals;
using test::NotifySocket;
using test::TempDir;

class NotifierTest : public ::testing::Test {
 protected:
  TempDir dir;
  NotifySocket sock{(dir.path() / "notify").string()};
  void SetUp() override { ::setenv("NOTIFY_SOCKET", sock.path().c_str(), 1); }
  void TearDown() override { ::unsetenv("NOTIFY_SOCKET"); }
};

TEST_F(NotifierTest, ReadyStatusStoppingArriveFromTheEnvironmentSocket) {
  Notifier n = Notifier::from_environment();
  ASSERT_TRUE(n.enabled());
  EXPECT_TRUE(n.ready("bus can0 up, store open"));
  EXPECT_EQ(sock.receive(1s), "READY=1\nSTATUS=bus can0 up, store open");
  EXPECT_TRUE(n.ready());
  EXPECT_EQ(sock.receive(1s), "READY=1");
  EXPECT_TRUE(n.status("draining outbox"));
  EXPECT_EQ(sock.receive(1s), "STATUS=draining outbox");
  EXPECT_TRUE(n.watchdog());
  EXPECT_EQ(sock.receive(1s), "WATCHDOG=1");
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(sock.receive(1s), "STOPPING=1");
  EXPECT_EQ(sock.receive(50ms), std::nullopt);
}

TEST(Notifier, AbstractNamespaceSocket) {
  const std::string name = "@fleetgw-test-notify-" + std::to_string(::getpid());
  NotifySocket sock(name);
  Notifier n(name);
  ASSERT_TRUE(n.enabled());
  EXPECT_TRUE(n.ready());
  EXPECT_EQ(sock.receive(1s), "READY=1");
}

TEST(Notifier, DisabledWithoutOrWithUnusableNotifySocket) {
  ::unsetenv("NOTIFY_SOCKET");
  Notifier none = Notifier::from_environment();
  EXPECT_FALSE(none.enabled());
  EXPECT_FALSE(none.ready());
  EXPECT_FALSE(none.watchdog());
  EXPECT_FALSE(Notifier("relative/path").enabled());
  EXPECT_FALSE(Notifier("vsock:2:1234").enabled());
  EXPECT_FALSE(Notifier("/" + std::string(200, 'x')).enabled());  // longer than sun_path
}

TEST(Notifier, NoListenerIsNotAnError) {
  TempDir dir;
  Notifier n((dir.path() / "nobody-listens").string());
  EXPECT_TRUE(n.enabled());
  EXPECT_FALSE(n.ready());  // reported, never thrown
}

TEST(WatchdogEnv, ParsesUsecAndHonoursPid) {
  EXPECT_EQ(parse_watchdog_env(nullptr, nullptr, 42), std::nullopt);
  EXPECT_EQ(parse_watchdog_env("20000000", nullptr, 42), std::chrono::microseconds(20'000'000));
  EXPECT_EQ(parse_watchdog_env("20000000", "42", 42), std::chrono::microseconds(20'000'000));
  EXPECT_EQ(parse_watchdog_env("20000000", "43", 42), std::nullopt);  // meant for another pid
  EXPECT_EQ(parse_watchdog_env("0", nullptr, 42), std::nullopt);
  EXPECT_EQ(parse_watchdog_env("12x", nullptr, 42), std::nullopt);
  EXPECT_EQ(parse_watchdog_env("", nullptr, 42), std::nullopt);
  EXPECT_EQ(parse_watchdog_env("-5", nullptr, 42), std::nullopt);
}

TEST_F(NotifierTest, WatchdogPingsAtHalfTheTimeout) {
  Notifier n = Notifier::from_environment();
  Watchdog w(n, 10s);
  EXPECT_EQ(w.ping_period(), 5s);
  EXPECT_LE(w.check_period(), w.ping_period() / 2);
  const Watchdog::Clock::time_point t0{};
  EXPECT_TRUE(w.loop_alive(t0));  // first call pings at once
  EXPECT_EQ(sock.receive(1s), "WATCHDOG=1");
  EXPECT_FALSE(w.loop_alive(t0 + 2s));
  EXPECT_FALSE(w.loop_alive(t0 + 4999ms));
  EXPECT_TRUE(w.loop_alive(t0 + 5s));
  EXPECT_EQ(sock.receive(1s), "WATCHDOG=1");
  // After a stall the next call pings at once (systemd has not fired yet or we would be dead).
  EXPECT_TRUE(w.loop_alive(t0 + 30s));
  EXPECT_EQ(w.pings(), 3u);
  EXPECT_EQ(sock.receive(1s), "WATCHDOG=1");
  EXPECT_EQ(sock.receive(50ms), std::nullopt);
}

// The property systemd relies on: pings come from the event loop itself, so they flow while the
// loop runs and stop while a handler blocks it.
TEST_F(NotifierTest, LoopWatchdogStopsPingingWhileTheLoopIsStalled) {
  const std::string pid = std::to_string(::getpid());
  ::setenv("WATCHDOG_USEC", "200000", 1);
  ::setenv("WATCHDOG_PID", pid.c_str(), 1);
  const auto timeout = watchdog_timeout_from_environment();
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  ASSERT_EQ(timeout, std::chrono::microseconds(200'000));

  using Clock = std::chrono::steady_clock;
  asio::io_context io;
  Notifier notifier = Notifier::from_environment();
  auto dog = std::make_unique<LoopWatchdog>(io, notifier, *timeout);
  dog->start();
  std::thread loop([&] { io.run(); });

  // Collects pings until `until`, returning their arrival times.
  auto collect = [&](Clock::time_point until) {
    std::vector<Clock::time_point> at;
    while (Clock::now() < until) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
      if (auto m = sock.receive(std::max(left, 1ms))) {
        EXPECT_EQ(*m, "WATCHDOG=1");
        at.push_back(Clock::now());
      }
    }
    return at;
  };

  const auto running = collect(Clock::now() + 600ms);
  EXPECT_GE(running.size(), 3u) << "pings every 100 ms while the loop runs";

  std::promise<Clock::time_point> stall_started;
  constexpr auto kStall = 900ms;
  asio::post(io, [&] {
    stall_started.set_value(Clock::now());
    std::this_thread::sleep_for(kStall);  // a hung handler
  });
  const auto s = stall_started.get_future().get();
  const auto during = collect(s + kStall - 50ms);
  // A ping already in the socket when the stall began may still be read just after it.
  const auto late = std::count_if(during.begin(), during.end(),
                                  [&](Clock::time_point t) { return t > s + 30ms; });
  EXPECT_EQ(late, 0) << "no ping may leave a stalled loop";

  const auto after = collect(Clock::now() + 600ms);
  EXPECT_GE(after.size(), 2u) << "pings resume once the loop runs again";

  // The timer belongs to the loop's thread: stop it there, then the loop runs out of work.
  asio::post(io, [&] { dog->stop(); });
  loop.join();
}

}  // namespace
}  // namespace fleetgw::status
