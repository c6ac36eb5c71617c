// Poller through the IotNode facade: model info read at start-up, the stale rule, retries and
// timeouts with exact send counts, back-off, answers on broadcast IDs, one request per ID.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "fake_bus.h"

namespace fleetgw::node::test {
namespace {

PollEntry entry(std::string name, uint16_t target, uint16_t command, MessageKey answer,
                Micros period) {
  return PollEntry{std::move(name), target, command, {answer}, period};
}

TEST(PollerTest, ModelInfoOfEveryNodeIsReadAtStartUp) {
  NodeConfig cfg = quiet_config();
  cfg.fitted_locks = {true, false, true, false, false};
  cfg.poll_table.reset();  // the default table
  FakeBus bus(cfg);
  bus.start();
  const Micros t0 = bus.now;
  // Own model info goes out at start-up too.
  EXPECT_EQ(bus.sender.count(0x760, 0x13), 1u);
  EXPECT_EQ(bus.sender.matching(0x763, 0x70).at(0).at, t0) << "OBC model info 0x763/0x7000";
  EXPECT_EQ(bus.sender.matching(0x767, 0x80).at(0).at, t0) << "LOCK 1 info 0x767/0x8000";
  EXPECT_EQ(bus.sender.matching(0x769, 0xA0).at(0).at, t0) << "LOCK 3 info 0x769/0xA000";
  EXPECT_EQ(bus.sender.count(0x768, 0x90), 0u) << "LOCK 2 is not fitted";
  EXPECT_EQ(bus.sender.matching(0x762, 0x51).at(0).at, t0) << "BMS model read 0x762/0x5100";
  // Only one request per ID: the BMS nameplate read waits for the model read.
  EXPECT_EQ(bus.sender.count(0x762, 0x53), 0u);
  // MC model info has no read in V4.6.2: nothing is sent to the MC for it.
  EXPECT_EQ(bus.sender.count(0x761, 0x12), 0u);

  // The OBC answers on its broadcast ID; the read stops and the registry has the model.
  bus.run_for(50ms);
  bus.deliver(peer_model_info(0x730, "OBC-7", "S-OBC-1"));
  bus.run_for(2s);
  EXPECT_EQ(bus.sender.count(0x763, 0x70), 1u);
  ASSERT_TRUE(bus.node->registry().node(Node::kObc).model.has_value());
  EXPECT_EQ(bus.node->registry().node(Node::kObc).model->model, "OBC-7");
}

TEST(PollerTest, UnansweredReadIsSentFiveTimesThenBacksOff) {
  NodeConfig cfg = quiet_config();
  cfg.poll_table = {entry("obc_model", 0x763, 0x7000, {0x730, 0x11}, 0s)};
  FakeBus bus(cfg);
  std::vector<PollResult> results;
  bus.node->set_poll_result_callback([&](const PollResult& r) { results.push_back(r); });
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 5500ms);
  const auto sends = bus.sender.matching(0x763, 0x70);
  ASSERT_EQ(sends.size(), 5u) << "retry every 200 ms, give up after 1 s";
  for (std::size_t i = 0; i < sends.size(); ++i) {
    EXPECT_EQ(sends[i].at - t0, 200ms * static_cast<int64_t>(i));
  }
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].entry->name, "obc_model");
  EXPECT_EQ(results[0].request.outcome, RequestOutcome::kTimedOut);
  EXPECT_EQ(results[0].request.latency, 1s);

  // Back-off: 5 s after the timeout, then 10 s after the next one.
  bus.run_until(t0 + 6s);
  EXPECT_EQ(bus.sender.matching(0x763, 0x70, t0 + 5500ms).size(), 1u);
  EXPECT_EQ(bus.sender.matching(0x763, 0x70).back().at, t0 + 6s);
  bus.run_until(t0 + 16s);
  EXPECT_EQ(bus.sender.count(0x763, 0x70), 10u);
  bus.run_until(t0 + 17s);
  EXPECT_EQ(bus.sender.count(0x763, 0x70), 11u);
  EXPECT_EQ(bus.sender.matching(0x763, 0x70).back().at, t0 + 17s);
}

TEST(PollerTest, AnswerOnBroadcastIdIsMatchedAndReported) {
  NodeConfig cfg = quiet_config();
  cfg.poll_table = {
      PollEntry{"mc_settings", 0x761, 0x3300, {{0x713, 0x54}, {0x710, 0x54}, {0x716, 0x54}}, 60s}};
  cfg.requests.startup_grace = 0s;
  FakeBus bus(cfg);
  std::vector<PollResult> results;
  bus.node->set_poll_result_callback([&](const PollResult& r) { results.push_back(r); });
  bus.responder = [](const AppFrame& sent, FakeBus& b) {
    // The MC answers the second transmission only, 30 ms later, on 0x713.
    if (sent.can_id == 0x761 && sent.function == 0x33 && b.sender.count(0x761, 0x33) == 2) {
      b.at(b.now + 30ms,
           motinova::MessageWriter(desc("mc_settings", 0x713), default_options()).frame());
    }
  };
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 3s);
  EXPECT_EQ(bus.sender.count(0x761, 0x33), 2u);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].request.outcome, RequestOutcome::kAnswered);
  EXPECT_EQ(results[0].request.latency, 230ms);
  EXPECT_EQ(results[0].request.answered_by, (MessageKey{0x713, 0x54}));
  EXPECT_EQ(bus.node->poller().status(0).answered, 1u);
}

TEST(PollerTest, BroadcastBlockIsOnlyRequestedWhenStale) {
  NodeConfig cfg = quiet_config();
  cfg.poll_table = {entry("bms_status", 0x762, 0x5000, {0x720, 0x10}, 1s)};
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  // The BMS broadcasts its status every 200 ms for 3 s, then falls silent.
  for (Micros t = t0 + 100ms; t < t0 + 3s; t += 200ms) bus.at(t, bms_status());
  bus.run_until(t0 + 3s);
  EXPECT_EQ(bus.sender.count(0x762, 0x50), 0u) << "fresh broadcasts suppress the read";
  bus.run_until(t0 + 4s);
  // Last broadcast at 2.9 s: stale at 3.9 s, read then.
  const auto sends = bus.sender.matching(0x762, 0x50);
  ASSERT_EQ(sends.size(), 1u);
  EXPECT_EQ(sends[0].at, t0 + 3900ms);
}

TEST(PollerTest, PeriodicEntryWaitsForTheStartUpGraceBeforeItsFirstRead) {
  NodeConfig cfg = quiet_config();
  cfg.poll_table = {entry("bms_pack_stats", 0x762, 0x5400, {0x725, 0x50}, 60s)};
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 990ms);
  EXPECT_EQ(bus.sender.count(0x762, 0x54), 0u);
  bus.run_until(t0 + 1s);
  EXPECT_EQ(bus.sender.count(0x762, 0x54), 1u);
}

TEST(PollerTest, NeverTwoOutstandingRequestsOnOneId) {
  NodeConfig cfg = quiet_config();
  cfg.fitted_locks = {true, true, true, true, true};
  cfg.poll_table.reset();  // the full default table: many entries share 0x762 and the lock IDs
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  bus.run_until(t0 + 30s);  // nobody answers: every request runs to its timeout
  for (uint16_t id : {0x761, 0x762, 0x763, 0x767, 0x768, 0x769, 0x76A, 0x76B}) {
    const auto sends = bus.sender.on_id(id);
    ASSERT_FALSE(sends.empty()) << std::hex << id;
    // Every request is exactly 5 identical consecutive transmissions, 200 ms apart, and the next
    // request on the ID starts no earlier than the previous one's 1 s timeout.
    ASSERT_EQ(sends.size() % 5, 0u) << std::hex << id;
    for (std::size_t g = 0; g + 5 <= sends.size(); g += 5) {
      for (std::size_t i = 1; i < 5; ++i) {
        EXPECT_EQ(sends[g + i].frame.function, sends[g].frame.function) << std::hex << id;
        EXPECT_EQ(sends[g + i].at - sends[g + i - 1].at, 200ms) << std::hex << id;
      }
      if (g + 5 < sends.size()) {
        EXPECT_GE(sends[g + 5].at - sends[g].at, 1s) << std::hex << id;
      }
    }
  }
}

TEST(PollerTest, ModelInfoIsReadAgainWhenTheNodeComesBack) {
  NodeConfig cfg = quiet_config();
  cfg.poll_table = {entry("obc_model", 0x763, 0x7000, {0x730, 0x11}, 0s)};
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  bus.run_for(20ms);
  bus.deliver(peer_model_info(0x730, "OBC-7", "S1"));
  bus.run_until(t0 + 10s);  // OBC silent: offline at ~3 s
  EXPECT_FALSE(bus.node->registry().online(Node::kObc));
  EXPECT_EQ(bus.sender.count(0x763, 0x70), 1u);
  bus.deliver(peer_fault_word("obc_faults", 0x730, 0));  // back (maybe another unit)
  bus.run_for(20ms);
  EXPECT_EQ(bus.sender.count(0x763, 0x70), 2u);
}

}  // namespace
}  // namespace fleetgw::node::test
