// GnssStage (gateway/runtime/stages.h) with a real GnssFeed under the real Engine, on a
// ManualEnv: gpsd's reconnects are timed by the engine's one back-off (runtime/backoff.h),
// never by the feed -- not before reconnect_min, doubling up to reconnect_max, and a connection
// lost while reading waits the back-off before its first reconnect. The fault-bit policy sees
// every refusal ("position unknown").
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <asio/io_context.hpp>
#include <chrono>
#include <string>

#include "env/env.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/runtime/engine.h"
#include "gateway/runtime/stages.h"
#include "tests/support/process.h"
#include "tests/support/wait.h"

namespace fleetgw::runtime {
namespace {

using namespace std::chrono_literals;

// A listening loopback TCP socket: a gpsd that accepts (a refusing one is tests/support
// free_loopback_port()).
struct ListeningPort {
  ListeningPort() {
    fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0 || ::listen(fd, 4) != 0) {
      ADD_FAILURE() << "no local port";
    }
    port = std::to_string(ntohs(addr.sin_port));
  }
  ~ListeningPort() {
    if (fd >= 0) ::close(fd);
  }
  ListeningPort(const ListeningPort&) = delete;
  ListeningPort& operator=(const ListeningPort&) = delete;
  int fd = -1;
  std::string port;
};

struct Rig {
  explicit Rig(const std::string& port) {
    gnss::GnssFeedOptions o;
    o.host = "127.0.0.1";
    o.port = port;
    o.reconnect_min = 1000ms;
    o.reconnect_max = 4000ms;
    feed = std::make_unique<gnss::GnssFeed>(io, o, env, [this] { engine.request_settle(); });
    stage = std::make_unique<GnssStage>(*feed, engine);
    engine.add(*stage, {}, Backoff::Options{.initial = o.reconnect_min, .max = o.reconnect_max});
  }
  ~Rig() { engine.stop(); }
  void settle() {
    engine.request_settle();
    io.poll();
  }
  EngineTime retry_at() const { return engine.backoff(*stage)->retry_at().value(); }

  asio::io_context io;
  ManualEnv env;
  Engine engine{io, env};
  std::unique_ptr<gnss::GnssFeed> feed;
  std::unique_ptr<GnssStage> stage;
};

TEST(GnssStage, ReconnectsAreTimedByTheEnginesBackOffNeverEarlier) {
  Rig rig(std::to_string(fleetgw::testing::free_loopback_port()));  // nothing listens: refused
  const auto t0 = rig.env.steady_now();
  rig.settle();
  EXPECT_EQ(rig.feed->connect_attempts(), 1u) << "the first attempt is the first settle's";
  EXPECT_EQ(rig.stage->fault, true) << "refused: position unknown, the fault bit is set";
  EXPECT_EQ(rig.retry_at(), t0 + 1s);

  rig.env.advance(999ms);
  rig.settle();
  EXPECT_EQ(rig.feed->connect_attempts(), 1u) << "not before reconnect_min";
  rig.env.advance(1ms);
  rig.settle();
  EXPECT_EQ(rig.feed->connect_attempts(), 2u);
  EXPECT_EQ(rig.retry_at(), t0 + 1s + 2s) << "the wait doubles";
  rig.env.advance(2s);
  rig.settle();
  EXPECT_EQ(rig.retry_at(), t0 + 3s + 4s);
  rig.env.advance(4s);
  rig.settle();
  EXPECT_EQ(rig.feed->connect_attempts(), 4u);
  EXPECT_EQ(rig.retry_at(), t0 + 7s + 4s) << "capped at reconnect_max";
}

TEST(GnssStage, ALostConnectionWaitsTheBackOffBeforeItsFirstReconnect) {
  ListeningPort gpsd;
  Rig rig(gpsd.port);
  rig.settle();
  ASSERT_TRUE(rig.feed->connected());
  EXPECT_EQ(rig.engine.backoff(*rig.stage)->failures(), 0);
  // gpsd accepts and goes away: the feed sees the socket close on the loop.
  const int conn = ::accept(gpsd.fd, nullptr, nullptr);
  ASSERT_GE(conn, 0);
  // Read what the client sent (its WATCH request) first, so that closing is an orderly end of
  // the stream, as when gpsd stops, not a reset.
  char buf[4096];
  while (::recv(conn, buf, sizeof buf, MSG_DONTWAIT) > 0) {
  }
  ::close(conn);
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        rig.io.poll();
        return !rig.feed->connected();
      },
      30s));
  rig.io.poll();  // the settle the feed's event requested
  const auto lost_at = rig.env.steady_now();
  EXPECT_EQ(rig.feed->connect_attempts(), 1u) << "no reconnect at once";
  EXPECT_EQ(rig.retry_at(), lost_at + 1s);
  EXPECT_EQ(rig.stage->fault, true);
  rig.env.advance(1s);
  rig.settle();
  EXPECT_EQ(rig.feed->connect_attempts(), 2u);
  EXPECT_TRUE(rig.feed->connected()) << "gpsd still listens: reconnected";
  EXPECT_EQ(rig.engine.backoff(*rig.stage)->failures(), 0) << "the success reset the back-off";
}

}  // namespace
}  // namespace fleetgw::runtime
