// GatewayCore's echoes: what the gateway transmits reaches the listeners (trackers, recorder,
// command service) AFTER the frame being handled, in transmit order, and never from inside a
// listener's own call (no re-entrance); each is the message the bus saw, decoded once per
// distinct message the node sends, never per transmission (encoded once, for the bus).
// Deterministic: no clock, no event loop.
#include <gtest/gtest.h>

#include <vector>

#include "gateway/can/transport.h"
#include "gateway/node/messages.h"
#include "gateway/node/transport_sender.h"
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

// The CAN frames the transport was given: what the bus saw.
struct CapturingTransport final : can::Transport {
  std::vector<motinova::CanFrame> wire;
  can::BusHealth h;
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame& f) override {
    wire.push_back(f);
    return true;
  }
  void stop() override {}
  const can::BusHealth& health() const override { return h; }
  std::string_view name() const override { return "capture"; }
};

// A decoded message by value (a DecodedMessage only holds views).
struct Seen {
  uint16_t can_id = 0;
  uint8_t function = 0;
  std::string name;
  std::vector<std::pair<std::string, int64_t>> raw;
  friend bool operator==(const Seen&, const Seen&) = default;
};
Seen seen_of(const motinova::DecodedMessage& m) {
  Seen s{m.frame->can_id, m.frame->function, std::string(m.name()), {}};
  for (const auto& v : m.values()) s.raw.emplace_back(std::string(v.field->name), v.raw);
  return s;
}

struct Keeping final : MessageListener {
  std::vector<Seen> seen;
  void on_message(const motinova::DecodedMessage& m, Micros) override {
    seen.push_back(seen_of(m));
  }
};

// The bus's frames reassembled and decoded, as a peer on the bus would see them.
struct BusDecoder final : motinova::FrameSink {
  explicit BusDecoder(const motinova::DecodeOptions& o) : options(o) {}
  const motinova::DecodeOptions& options;
  std::vector<Seen> seen;
  void on_frame(const motinova::AppFrame& f, Micros) override {
    motinova::DecodedMessage m;
    motinova::decode(f, motinova::Catalogue::standard(), options, m);
    seen.push_back(seen_of(m));
  }
  void on_error(const motinova::ReassemblyErrorEvent&) override { ADD_FAILURE() << "bad frame"; }
};

TEST(EchoOrder, ListenersGetWhatTheBusSawDecodedOncePerDistinctMessageNotPerTransmission) {
  const auto cfg = make_config();
  CapturingTransport bus;
  node::TransportSender sender(bus, cfg.protocol.crc_order);
  GatewayCore core(cfg, sender);
  Keeping listener;
  core.add_listener(listener);
  const Micros t0 = sec(1'717'228'800);
  core.start(t0);
  core.node().vehicle_lock(t0);
  core.node().vehicle_unlock(t0);
  core.deliver_echoes();
  const auto decodes = core.stats().echo_decodes;
  const auto echoes = core.stats().echoes;
  EXPECT_EQ(echoes, listener.seen.size());

  for (int i = 0; i < 10; ++i) {
    core.node().vehicle_lock(t0 + ms(i));
    core.node().vehicle_unlock(t0 + ms(i));
    core.deliver_echoes();
  }
  EXPECT_EQ(core.stats().echoes, echoes + 20);
  EXPECT_EQ(core.stats().echo_decodes, decodes) << "a message already sent is not decoded again";
  EXPECT_LE(decodes, echoes);

  // Every message the listener got is the message the bus carried, in the same order.
  motinova::Reassembler reassembler;
  BusDecoder peer(core.options());
  for (const auto& f : bus.wire) reassembler.push(f, t0, peer);
  ASSERT_EQ(peer.seen.size(), listener.seen.size());
  EXPECT_EQ(peer.seen, listener.seen);
  EXPECT_EQ(listener.seen.back().can_id, kVehicleLockId);
  EXPECT_EQ(listener.seen.back().name, peer.seen.back().name);
}

}  // namespace
}  // namespace fleetgw::runtime::testing
