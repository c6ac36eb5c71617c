// IotNode::next_event(): the node tells the runtime when it next has something to do, so the
// runtime needs no periodic tick. Ticking only at those deadlines must give exactly the spec's
// timing (retries every 200 ms, timeout at 1 s, fault word every 1 s, model info every 10 s,
// offline after 3 s) with a handful of wake-ups instead of one every 10-50 ms.
#include <gtest/gtest.h>

#include "fake_bus.h"
#include "gateway/node/request_engine.h"

namespace fleetgw::node::test {
namespace {

std::vector<Micros> offsets(const std::vector<RecordingSender::Sent>& sends, Micros t0) {
  std::vector<Micros> out;
  for (const auto& s : sends) out.push_back(s.at - t0);
  return out;
}

TEST(NextEventTest, RequestRetriesAndTimeoutAreExactWhenTickedOnlyAtDeadlines) {
  Micros now{5'000'000};
  RecordingSender sender{now};
  RequestEngine engine{sender};
  EXPECT_EQ(engine.next_event(), Micros::max()) << "nothing outstanding";
  std::vector<RequestResult> results;
  Request r;
  r.frame = read_request(0x762, 0x50);
  r.answers = {{0x720, 0x10}};
  const Micros t0 = now;
  engine.submit(
      r, [&](const RequestResult& res) { results.push_back(res); }, now);
  int ticks = 0;
  while (engine.next_event() != Micros::max() && ticks < 100) {
    now = engine.next_event();
    engine.tick(now);
    ++ticks;
  }
  EXPECT_EQ(offsets(sender.matching(0x762, 0x50), t0),
            (std::vector<Micros>{0ms, 200ms, 400ms, 600ms, 800ms}));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, RequestOutcome::kTimedOut);
  EXPECT_EQ(results[0].completed, t0 + 1s);
  EXPECT_EQ(ticks, 5) << "four retries and the timeout, nothing else";
}

TEST(NextEventTest, IdleNodeBroadcastsOnScheduleWithOneWakeUpPerBroadcast) {
  NodeConfig cfg = quiet_config();
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  const int ticks = bus.run_by_deadline(t0 + 25s);
  EXPECT_EQ(offsets(bus.sender.matching(0x760, 0x13), t0), (std::vector<Micros>{0s, 10s, 20s}));
  const auto words = bus.sender.matching(0x760, 0x15);
  ASSERT_EQ(words.size(), 26u) << "fault word at start and every second";
  for (std::size_t i = 1; i < words.size(); ++i) {
    EXPECT_EQ(words[i].at - words[i - 1].at, 1s) << "fault word " << i;
  }
  // 25 fault words (model info shares their instants): a 50 ms tick would have been 500.
  EXPECT_LE(ticks, 25);
}

TEST(NextEventTest, NodeGoesOfflineExactlyAtTheTimeout) {
  FakeBus bus(quiet_config());
  bus.start();
  const Micros heard = bus.now + 100ms;
  bus.at(heard, bms_status());
  bus.run_by_deadline(heard + 2999ms);
  EXPECT_TRUE(bus.node->registry().online(Node::kBms));
  EXPECT_LE(bus.node->next_event(), heard + 3s);
  bus.run_by_deadline(heard + 3s);
  EXPECT_FALSE(bus.node->registry().online(Node::kBms)) << "offline at exactly 3 s";
}

TEST(NextEventTest, FaultyWordRepeatsEvery200msAndLockJobStepsAreScheduled) {
  NodeConfig cfg = quiet_config();
  cfg.fitted_locks[0] = true;
  FakeBus bus(cfg);
  const Micros t0 = bus.now;
  bus.start();
  bus.node->set_own_fault(0x0001, true, bus.now);
  bus.run_by_deadline(t0 + 1s);
  const auto words = bus.sender.matching(0x760, 0x15, t0 + 1ms);
  ASSERT_GE(words.size(), 4u);
  for (std::size_t i = 1; i < words.size(); ++i) {
    EXPECT_EQ(words[i].at - words[i - 1].at, 200ms) << "faulty word " << i;
  }
  // A lock job that gets no answer: its deadline is on the schedule and ends it on time.
  std::optional<LockResult> done;
  const Micros start = bus.now;
  ASSERT_EQ(bus.node->actuate_lock(0, LockTarget::kLocked, bus.now,
                                   [&](const LockResult& r) { done = r; }),
            LockStart::kStarted);
  EXPECT_LE(bus.node->next_event(), start + cfg.locks.timeout);
  EXPECT_TRUE(bus.node->latency_critical());
  bus.run_by_deadline(start + cfg.locks.timeout);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->outcome, LockOutcome::kTimeout);
  EXPECT_EQ(done->elapsed, cfg.locks.timeout);
  EXPECT_FALSE(bus.node->latency_critical());
}

}  // namespace
}  // namespace fleetgw::node::test
