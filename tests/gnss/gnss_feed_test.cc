// GnssFeed reads time only from the Env it is given and never times its own reconnects: it
// connects when its owner asks (the engine's back-off decides when: tests/runtime
// test_gnss_stage.cc), however far the clock moves and however often its timer fires.
#include "gateway/gnss/gnss_feed.h"

#include <gtest/gtest.h>

#include <asio/io_context.hpp>
#include <string>

#include "env/env.h"
#include "tests/support/process.h"

namespace fleetgw::gnss {
namespace {

using namespace std::chrono_literals;

TEST(GnssFeed, ConnectsOnlyWhenAskedAndKeepsNoRetryTimerOfItsOwn) {
  asio::io_context io;
  ManualEnv env;
  GnssFeedOptions o;
  o.host = "127.0.0.1";
  o.port = std::to_string(fleetgw::testing::free_loopback_port());  // nothing listens: refused
  int events = 0;
  GnssFeed feed(io, o, env, [&] { ++events; });
  EXPECT_EQ(feed.wall_now(), env.wall_now());
  EXPECT_TRUE(feed.needs_connect());
  EXPECT_EQ(feed.connect_attempts(), 0u) << "constructing a feed connects nothing";

  const auto error = feed.connect();  // refused: the reason is the owner's to report
  ASSERT_TRUE(error.has_value());
  EXPECT_NE(error->find("127.0.0.1:" + o.port), std::string::npos) << *error;
  EXPECT_FALSE(feed.connected());
  EXPECT_TRUE(feed.needs_connect());
  EXPECT_EQ(feed.state().reason(env.wall_now()), "gpsd unreachable");
  EXPECT_EQ(feed.take_loss(), std::nullopt) << "a refusal is not a loss";

  // No deadline of its own for the retry, and its timer never reconnects.
  EXPECT_EQ(feed.next_deadline(), std::nullopt);
  for (int i = 0; i < 5; ++i) {
    env.advance(60s);
    feed.on_timer();
  }
  EXPECT_EQ(feed.connect_attempts(), 1u);

  feed.stop();
  EXPECT_FALSE(feed.needs_connect());
  EXPECT_EQ(feed.connect(), std::nullopt);
  EXPECT_EQ(feed.connect_attempts(), 1u) << "a stopped feed does not connect";
}

}  // namespace
}  // namespace fleetgw::gnss
