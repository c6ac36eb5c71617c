// GatewayCore's echoes: what the gateway transmits reaches the listeners (trackers, recorder,
// command service) AFTER the frame being handled, in transmit order, and never from inside a
// listener's own call (no re-entrance). Deterministic: no clock, no event loop.
#include <gtest/gtest.h>

#include <vector>

#include "gateway/node/messages.h"
#include "motinova/segmenter.h"
#include "runtime_test_util.h"

namespace fleetgw::runtime::testing {
namespace {

constexpr uint16_t kVehicleLockId = 0x760;  // the gateway's own broadcasts (node 6)

struct AcceptingSender final : node::FrameSender {
  std::vector<motinova::AppFrame> sent;
  bool send(const motinova::AppFrame& f) override {
    sent.push_back(f);
    return true;
  }
};

// Records every message with the nesting depth it was delivered at.
struct Recording final : MessageListener {
  struct Seen {
    uint16_t can_id;
    int depth;
  };
  std::vector<Seen> seen;
  int depth = 0;
  int max_depth = 0;
  std::function<void(const motinova::DecodedMessage&, Micros)> react;
  void on_message(const motinova::DecodedMessage& m, Micros now) override {
    ++depth;
    max_depth = std::max(max_depth, depth);
    seen.push_back({m.frame->can_id, depth});
    if (react) react(m, now);
    --depth;
  }
};

std::vector<motinova::CanFrame> lock_status_frames() {
  std::array<uint8_t, node::kLockStatusLength> data{};
  data[node::kLockStateOffset] = node::lock_state::kLocked;
  const auto frame = motinova::make_frame(node::ids::lock_broadcast_id(0), motinova::Mode::kReport,
                                          node::fn::kLockStatus, data);
  return motinova::segment(frame);
}

TEST(EchoOrder, ReactionToAFrameReachesListenersAfterTheFrameAndWithoutReentrance) {
  const auto cfg = make_config();
  AcceptingSender sender;
  GatewayCore core(cfg, sender);
  Recording reacting;  // like the command service: sends from inside on_message
  Recording observer;  // like the trackers: only listens
  core.add_listener(reacting);
  core.add_listener(observer);
  const Micros t0 = sec(1'717'228'800);
  core.start(t0);
  sender.sent.clear();
  reacting.seen.clear();
  observer.seen.clear();

  bool sent_once = false;
  reacting.react = [&](const motinova::DecodedMessage& m, Micros now) {
    if (sent_once || m.frame->can_id != node::ids::lock_broadcast_id(0)) return;
    sent_once = true;
    core.node().vehicle_lock(now);  // transmits 0x760 LOCK while the frame is being handled
  };
  for (const auto& can : lock_status_frames()) core.on_can_frame(can, t0 + ms(10));

  ASSERT_TRUE(sent_once);
  ASSERT_FALSE(sender.sent.empty());
  EXPECT_EQ(sender.sent.front().can_id, kVehicleLockId);
  // Both listeners: first the lock's status, then the gateway's LOCK broadcast.
  for (const Recording* r : {&reacting, &observer}) {
    ASSERT_GE(r->seen.size(), 2u);
    EXPECT_EQ(r->seen[0].can_id, node::ids::lock_broadcast_id(0));
    EXPECT_EQ(r->seen[1].can_id, kVehicleLockId);
    EXPECT_EQ(r->max_depth, 1) << "a listener was re-entered by an echo";
  }
  EXPECT_FALSE(core.echoes_pending());
}

TEST(EchoOrder, SendsFromOutsideTheCoreWaitForDeliverEchoes) {
  const auto cfg = make_config();
  AcceptingSender sender;
  GatewayCore core(cfg, sender);
  Recording observer;
  core.add_listener(observer);
  const Micros t0 = sec(1'717'228'800);
  core.start(t0);
  observer.seen.clear();

  // The command service acts on the node outside any frame: nothing reaches the listeners
  // while it runs; the pipeline delivers the echoes when the call has returned.
  core.node().vehicle_lock(t0 + ms(5));
  core.node().vehicle_unlock(t0 + ms(5));
  EXPECT_TRUE(observer.seen.empty());
  EXPECT_TRUE(core.echoes_pending());
  core.deliver_echoes();
  ASSERT_EQ(observer.seen.size(), 2u);
  EXPECT_EQ(observer.seen[0].can_id, kVehicleLockId);
  EXPECT_EQ(observer.seen[1].can_id, kVehicleLockId);
  EXPECT_FALSE(core.echoes_pending());
}

}  // namespace
}  // namespace fleetgw::runtime::testing
