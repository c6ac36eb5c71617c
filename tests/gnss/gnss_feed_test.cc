// GnssFeed reads time only from the Env it is given: with a ManualEnv standing still, its
// reconnect back-off, its deadlines and the ageing of what it knows are decided on the test's
// clock, without sleeping (a feed that read the machine's clocks would miss every exact value
// below: the ManualEnv's steady clock is at 1 s, the machine's at its uptime).
#include "gateway/gnss/gnss_feed.h"

#include <gtest/gtest.h>

#include <asio/io_context.hpp>
#include <string>

#include "env/env.h"
#include "tests/support/process.h"

namespace fleetgw::gnss {
namespace {

using namespace std::chrono_literals;

TEST(GnssFeed, BackOffAndAgeingRunOnTheInjectedClock) {
  asio::io_context io;
  ManualEnv env;
  GnssFeedOptions o;
  o.host = "127.0.0.1";
  o.port = std::to_string(fleetgw::testing::free_loopback_port());  // nothing listens: refused
  o.reconnect_min = 1000ms;
  o.reconnect_max = 4000ms;
  int events = 0;
  GnssFeed feed(io, o, env, [&] { ++events; });
  EXPECT_EQ(feed.wall_now(), env.wall_now());

  feed.start();  // refused: unknown since now, retried after reconnect_min
  ASSERT_FALSE(feed.connected());
  EXPECT_EQ(feed.state().reason(env.wall_now()), "gpsd unreachable");
  const auto t0 = env.steady_now();
  EXPECT_EQ(feed.next_deadline(), t0 + 1000ms);

  // The timer fires early (the owner's timer is shared): nothing is retried before its time.
  env.advance(999ms);
  feed.on_timer();
  EXPECT_EQ(feed.next_deadline(), t0 + 1000ms);

  // At its time the retry happens, fails again and the back-off doubles, up to reconnect_max.
  env.advance(1ms);
  feed.on_timer();
  EXPECT_EQ(feed.next_deadline(), t0 + 1000ms + 2000ms);
  env.advance(2000ms);
  feed.on_timer();
  EXPECT_EQ(feed.next_deadline(), t0 + 3000ms + 4000ms);
  env.advance(4000ms);
  feed.on_timer();
  EXPECT_EQ(feed.next_deadline(), t0 + 7000ms + 4000ms) << "capped at reconnect_max";
}

}  // namespace
}  // namespace fleetgw::gnss
