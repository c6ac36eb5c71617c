// Own broadcasts on 0x760: model info, the fault-word period that follows the faults, READY in
// answer to SHUTDOWN, vehicle LOCK/UNLOCK.
#include <gtest/gtest.h>

#include "fake_bus.h"

namespace fleetgw::node::test {
namespace {

motinova::DecodedMessage decoded(const AppFrame& f) {
  motinova::DecodedMessage msg;
  motinova::decode(f, motinova::Catalogue::standard(), default_options(), msg);
  return msg;
}

std::vector<Micros> offsets(const std::vector<RecordingSender::Sent>& sends, Micros t0) {
  std::vector<Micros> out;
  for (const auto& s : sends) out.push_back(s.at - t0);
  return out;
}

TEST(BroadcastTest, ModelInfoAtStartUpAndEvery10s) {
  NodeConfig cfg = quiet_config();
  cfg.identity.model = "FLEETGW-E1";
  cfg.identity.hardware = "HW1.2";
  cfg.identity.firmware_version = "0.1.0";
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 25s);
  const auto sends = bus.sender.matching(0x760, 0x13);
  EXPECT_EQ(offsets(sends, t0), (std::vector<Micros>{0s, 10s, 20s}));
  const AppFrame& f = sends.at(0).frame;
  EXPECT_EQ(f.mode, motinova::Mode::kReport);
  const auto msg = decoded(f);
  ASSERT_NE(msg.desc, nullptr);
  EXPECT_EQ(msg.name(), "device_info");
  EXPECT_EQ(msg.text("model"), "FLEETGW-E1");
  EXPECT_EQ(msg.text("serial"), "SN0001");
  EXPECT_EQ(msg.text("hw"), "HW1.2");
  EXPECT_EQ(msg.text("fw"), "V0.1.0_20250301");
  EXPECT_EQ(f.data[63], 0x20) << "space padded";
}

TEST(BroadcastTest, FaultWordPeriodFollowsTheFaults) {
  FakeBus bus(quiet_config());
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 1500ms);
  bus.node->set_own_fault(iot_fault::kGps, true, bus.now);  // at 1.5 s: sent at once
  bus.run_until(t0 + 2050ms);
  bus.node->set_own_fault(iot_fault::kBle, true, bus.now);  // change at 2.05 s: at once again
  bus.run_until(t0 + 2500ms);
  bus.node->set_own_faults(0, bus.now);  // cleared at 2.5 s: at once, then back to 1 s
  bus.run_until(t0 + 4600ms);

  const auto sends = bus.sender.matching(0x760, 0x15);
  const std::vector<Micros> expected{0s,     1s,     1500ms, 1700ms, 1900ms, 2050ms,
                                     2250ms, 2450ms, 2500ms, 3500ms, 4500ms};
  EXPECT_EQ(offsets(sends, t0), expected);
  std::vector<uint32_t> words;
  for (const auto& s : sends) words.push_back(static_cast<uint32_t>(*decoded(s.frame).raw("raw")));
  const std::vector<uint32_t> expected_words{0, 0, 4, 4, 4, 6, 6, 6, 0, 0, 0};
  EXPECT_EQ(words, expected_words);
  // Setting a bit that is already set is not a change.
  bus.node->set_own_fault(iot_fault::kUplinkModule, false, bus.now);
  EXPECT_EQ(bus.sender.count(0x760, 0x15), sends.size());
}

TEST(BroadcastTest, ReadyAnswersObcAndBmsShutdownAtOnceAndIsRepeated) {
  std::vector<Node> hooked;
  std::size_t ready_before_hook = 99;
  NodeHooks hooks;
  FakeBus* bus_ptr = nullptr;
  hooks.on_peer_shutdown = [&](Node initiator, Micros) {
    hooked.push_back(initiator);
    ready_before_hook = bus_ptr->sender.count(0x760, 0x14);
  };
  FakeBus bus(quiet_config(), hooks);
  bus_ptr = &bus;
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 1s);
  bus.deliver(peer_keyword("shutdown", 0x730));
  ASSERT_EQ(hooked.size(), 1u);
  EXPECT_EQ(hooked[0], Node::kObc);
  EXPECT_EQ(ready_before_hook, 0u) << "the hook (save state) runs before READY goes out";
  bus.run_until(t0 + 2s);
  const auto readies = bus.sender.matching(0x760, 0x14);
  // Immediately (well within 200 ms), then 2 repeats 200 ms apart (U12).
  EXPECT_EQ(offsets(readies, t0), (std::vector<Micros>{1s, 1200ms, 1400ms}));
  const auto msg = decoded(readies.at(0).frame);
  EXPECT_EQ(msg.name(), "ready");
  EXPECT_TRUE(is_keyword(readies[0].frame, "READY"));

  bus.deliver(peer_keyword("shutdown", 0x720));  // BMS 0x720/0x1308
  EXPECT_EQ(bus.sender.count(0x760, 0x14), 4u);
  EXPECT_EQ(hooked.back(), Node::kBms);
}

TEST(BroadcastTest, OwnShutdownEchoAndOtherKeywordsAreNotAnswered) {
  FakeBus bus(quiet_config());
  bus.start();
  bus.deliver(peer_keyword("shutdown", 0x760));  // our own ID (transport echo)
  bus.deliver(peer_keyword("ready", 0x710));
  bus.deliver(peer_keyword("ready", 0x730));
  bus.run_for(1s);
  EXPECT_EQ(bus.sender.count(0x760, 0x14), 0u);
}

TEST(BroadcastTest, VehicleUnlockCancelsPendingLockRepeats) {
  FakeBus bus(quiet_config());
  const Micros t0 = bus.now;
  bus.start();
  bus.node->vehicle_lock(bus.now);
  bus.run_until(t0 + 300ms);  // LOCK at 0 and 200 ms
  bus.node->vehicle_unlock(bus.now);
  bus.run_until(t0 + 2s);
  EXPECT_EQ(offsets(bus.sender.matching(0x760, 0x11), t0), (std::vector<Micros>{0s, 200ms}));
  EXPECT_EQ(offsets(bus.sender.matching(0x760, 0x12), t0),
            (std::vector<Micros>{300ms, 500ms, 700ms}));
  const AppFrame unlock = bus.sender.matching(0x760, 0x12).at(0).frame;
  EXPECT_TRUE(is_keyword(unlock, "UNLOCK"));
  // Spec test vector T6: IOT LOCK on 0x760.
  const auto wire = motinova::encode_frame(bus.sender.matching(0x760, 0x11).at(0).frame);
  const std::vector<uint8_t> t6{0x55, 0xAA, 0x0C, 0x06, 0x11, 0x04, 0x4C, 0x4F,
                                0x43, 0x4B, 0xEB, 0x70, 0xB9, 0xFC, 0xF0};
  EXPECT_EQ(std::vector<uint8_t>(wire.begin(), wire.end()), t6);
}

}  // namespace
}  // namespace fleetgw::node::test
