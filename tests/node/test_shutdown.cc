// The IoT-initiated shutdown of §3.8.2: SHUTDOWN, wait for READY from MC and OBC or 1 s, ACC off.
#include <gtest/gtest.h>

#include "fake_bus.h"

namespace fleetgw::node::test {
namespace {

struct ShutdownTest : ::testing::Test {
  std::vector<std::pair<ShutdownOutcome, Micros>> acc_off;
  std::unique_ptr<FakeBus> bus;
  Micros t0{};

  void make(NodeConfig cfg = quiet_config()) {
    NodeHooks hooks;
    hooks.acc_off = [this](const ShutdownOutcome& o) { acc_off.emplace_back(o, bus->now); };
    bus = std::make_unique<FakeBus>(std::move(cfg), std::move(hooks));
    bus->start();
  }
  void mc_and_obc_online() {
    bus->deliver(peer_fault_word("mc_faults", 0x710, 0));
    bus->deliver(peer_fault_word("obc_faults", 0x730, 0));
    t0 = bus->now;
  }
};

TEST_F(ShutdownTest, WaitsForBothReadiesThenSwitchesAccOff) {
  make();
  mc_and_obc_online();
  ASSERT_TRUE(bus->node->start_shutdown(bus->now));
  const auto shutdown = bus->sender.matching(0x760, 0x10);
  ASSERT_EQ(shutdown.size(), 1u);
  EXPECT_TRUE(is_keyword(shutdown[0].frame, "SHUTDOWN"));
  // Spec test vector T7.
  const auto wire = motinova::encode_frame(shutdown[0].frame);
  EXPECT_EQ(wire.size(), 19u);
  EXPECT_EQ(wire[14], 0xF8);
  EXPECT_EQ(wire[17], 0xA0);
  EXPECT_FALSE(bus->node->start_shutdown(bus->now)) << "one procedure at a time";

  bus->at(t0 + 100ms, peer_keyword("ready", 0x710));
  bus->at(t0 + 300ms, peer_keyword("ready", 0x730));
  bus->run_until(t0 + 2s);
  ASSERT_EQ(acc_off.size(), 1u);
  const auto& [o, at] = acc_off[0];
  EXPECT_EQ(at, t0 + 300ms) << "ACC off as soon as the last READY arrived";
  EXPECT_TRUE(o.awaited_mc && o.awaited_obc);
  EXPECT_TRUE(o.mc_ready);
  EXPECT_TRUE(o.obc_ready);
  EXPECT_FALSE(o.timed_out);
  EXPECT_EQ(o.elapsed, 300ms);
  // SHUTDOWN repeats (200 ms) stop once everyone is ready: 0 and 200 ms only.
  EXPECT_EQ(bus->sender.count(0x760, 0x10), 2u);
  EXPECT_FALSE(bus->node->shutdown_running());
  EXPECT_EQ(bus->sender.count(0x763, 0x70), 0u) << "order_obc_off is off by default";
}

TEST_F(ShutdownTest, WithoutReadiesAccGoesOffAfter1s) {
  make();
  mc_and_obc_online();
  bus->node->start_shutdown(bus->now);
  bus->at(t0 + 100ms, peer_keyword("ready", 0x710));  // only the MC answers
  bus->run_until(t0 + 990ms);
  EXPECT_TRUE(acc_off.empty());
  bus->run_until(t0 + 2s);
  ASSERT_EQ(acc_off.size(), 1u);
  const auto& [o, at] = acc_off[0];
  EXPECT_EQ(at, t0 + 1s);
  EXPECT_TRUE(o.timed_out);
  EXPECT_TRUE(o.mc_ready);
  EXPECT_FALSE(o.obc_ready);
  EXPECT_EQ(bus->sender.count(0x760, 0x10), 3u) << "sent and repeated twice";
}

TEST_F(ShutdownTest, ReadyHeardBeforeStartDoesNotCount) {
  make();
  mc_and_obc_online();
  bus->deliver(peer_keyword("ready", 0x710));
  bus->deliver(peer_keyword("ready", 0x730));
  bus->node->start_shutdown(bus->now);
  bus->run_until(t0 + 2s);
  ASSERT_EQ(acc_off.size(), 1u);
  EXPECT_TRUE(acc_off[0].first.timed_out);
}

TEST_F(ShutdownTest, OnlyOnlineNodesAreAwaited) {
  make();
  bus->deliver(peer_fault_word("mc_faults", 0x710, 0));  // the OBC is not fitted
  t0 = bus->now;
  bus->node->start_shutdown(bus->now);
  bus->at(t0 + 50ms, peer_keyword("ready", 0x710));
  bus->run_until(t0 + 2s);
  ASSERT_EQ(acc_off.size(), 1u);
  EXPECT_EQ(acc_off[0].second, t0 + 50ms);
  EXPECT_FALSE(acc_off[0].first.awaited_obc);
  EXPECT_FALSE(acc_off[0].first.timed_out);
}

TEST_F(ShutdownTest, NobodyToWaitForSwitchesOffAtOnce) {
  make();
  const Micros start = bus->now;
  bool own_callback = false;
  bus->node->start_shutdown(bus->now, [&](const ShutdownOutcome& o) {
    own_callback = true;
    EXPECT_FALSE(o.timed_out);
    EXPECT_EQ(o.elapsed, 0s);
  });
  EXPECT_TRUE(own_callback);
  EXPECT_TRUE(acc_off.empty()) << "an explicit callback replaces hooks.acc_off";
  bus->run_until(start + 1s);
  EXPECT_EQ(bus->sender.count(0x760, 0x10), 3u) << "repeats still run for the BMS";
}

TEST_F(ShutdownTest, OrderObcOffSendsTheDirectedShutdown) {
  NodeConfig cfg = quiet_config();
  cfg.shutdown.order_obc_off = true;
  make(cfg);
  mc_and_obc_online();
  bus->node->start_shutdown(bus->now);
  const auto order = bus->sender.matching(0x763, 0x70);
  ASSERT_EQ(order.size(), 1u);
  EXPECT_EQ(order[0].frame.mode, motinova::Mode::kWrite);
  EXPECT_TRUE(is_keyword(order[0].frame, "SHUTDOWN"));
  EXPECT_EQ(order[0].frame.command(), 0x7008);
}

}  // namespace
}  // namespace fleetgw::node::test
