// The zone-bundle queue between Paho's thread and the engine loop (gateway/uplink/uplink.h,
// "Zone bundles"), against a real mosquitto: the messages reach Uplink through the very
// message-arrived callback Paho calls, so the bound is exercised where it applies. While the
// owner takes nothing, at most max_queued_zone_bundles (4) wait; later arrivals are dropped,
// logged and counted, and the ones kept are the oldest, in arrival order (a retained bundle
// comes again at the next connect, so what is dropped is not lost for good). Once taken, the
// queue has room again.
#include <gtest/gtest.h>

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/uplink_test_util.h"

namespace fleetgw::uplink {
namespace {

using namespace std::chrono_literals;
using testing::drive;
using testing::MosquittoBroker;
using testing::plain_config;
using testing::Subscriber;
using testing::wall_now;

// Adds a ring-buffer sink to the default logger for the test's lifetime.
class LogCapture {
 public:
  LogCapture() { spdlog::default_logger()->sinks().push_back(sink_); }
  ~LogCapture() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  int count(const std::string& text) const {
    const auto lines = sink_->last_formatted();
    return static_cast<int>(std::count_if(lines.begin(), lines.end(), [&](const std::string& l) {
      return l.find(text) != std::string::npos;
    }));
  }

 private:
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_ =
      std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(256);
};

TEST(UplinkMqtt, ZoneBundleQueueKeepsTheOldestFourAndCountsAndLogsTheDrops) {
  const LogCapture log;
  MosquittoBroker broker;
  broker.start();
  const std::string zones = "fleet/v1/zones";
  Subscriber operator_client(broker.uri(), "fleet/v1/bike-z/status", "operator-z");
  MemoryOutbox box;
  auto cfg = plain_config(broker.uri(), "bike-z");
  cfg.zone_topics = {zones};
  ASSERT_EQ(cfg.max_queued_zone_bundles, 4u) << "the documented default this test is about";
  Uplink up(cfg, box);
  up.start(wall_now());
  // The status publish is acknowledged after the subscriptions made before it on the same
  // connection: the zone topic is subscribed from then on.
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().acked_messages >= 1; }, 10s));

  constexpr int kSent = 7;
  for (int i = 0; i < kSent; ++i) {
    operator_client.client().publish(zones, "bundle-" + std::to_string(i), 1, false)->wait();
  }
  // The owner polls but takes nothing: every arrival is either queued or dropped.
  ASSERT_TRUE(drive(
      up,
      [&] {
        const UplinkStats s = up.stats();
        return s.zone_bundles_received + s.zone_bundles_dropped == kSent;
      },
      10s))
      << up.stats().zone_bundles_received << " received, " << up.stats().zone_bundles_dropped
      << " dropped";
  EXPECT_EQ(up.stats().zone_bundles_received, 4u);
  EXPECT_EQ(up.stats().zone_bundles_dropped, 3u);
  EXPECT_EQ(log.count("dropped message on fleet/v1/zones: zone bundle queue full"), 3);

  const std::vector<ZoneBundleMessage> kept = up.take_zone_bundles();
  ASSERT_EQ(kept.size(), 4u);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    EXPECT_EQ(kept[i].topic, zones);
    EXPECT_EQ(kept[i].payload, "bundle-" + std::to_string(i)) << "the oldest, in arrival order";
    EXPECT_EQ(kept[i].oversized_bytes, 0u);
  }
  EXPECT_TRUE(up.take_zone_bundles().empty());

  // Taken: the queue has room again, and the drop count stays what it was.
  operator_client.client().publish(zones, std::string("bundle-next"), 1, false)->wait();
  std::vector<ZoneBundleMessage> later;
  ASSERT_TRUE(drive(
      up,
      [&] {
        for (auto& b : up.take_zone_bundles()) later.push_back(std::move(b));
        return !later.empty();
      },
      10s));
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].payload, "bundle-next");
  EXPECT_EQ(up.stats().zone_bundles_received, 5u);
  EXPECT_EQ(up.stats().zone_bundles_dropped, 3u);
  EXPECT_EQ(up.state(), UplinkState::kConnected);
}

}  // namespace
}  // namespace fleetgw::uplink
