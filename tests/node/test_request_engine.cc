// RequestEngine: retry cadence, timeout, answer matching on broadcast IDs, one outstanding
// request per target ID.
#include <gtest/gtest.h>

#include "fake_bus.h"
#include "gateway/node/request_engine.h"

namespace fleetgw::node::test {
namespace {

class RequestEngineTest : public ::testing::Test {
 protected:
  Micros now{5'000'000};
  RecordingSender sender{now};
  RequestEngine engine{sender};
  std::vector<RequestResult> results;

  RequestEngine::Callback record() {
    return [this](const RequestResult& r) { results.push_back(r); };
  }
  Request read(uint16_t target, uint8_t function, MessageKey answer) {
    Request r;
    r.frame = read_request(target, function);
    r.answers = {answer};
    return r;
  }
  void advance(Micros until, Micros step = 10ms) {
    while (now < until) {
      now += step;
      engine.tick(now);
    }
  }
};

TEST_F(RequestEngineTest, RetriesEvery200msAndTimesOutAfter1sWithFiveTransmissions) {
  const Micros t0 = now;
  engine.submit(read(0x762, 0x50, {0x720, 0x10}), record(), now);
  advance(t0 + 2s);
  const auto sends = sender.matching(0x762, 0x50);
  ASSERT_EQ(sends.size(), 5u);
  for (std::size_t i = 0; i < sends.size(); ++i) {
    EXPECT_EQ(sends[i].at - t0, Micros{200'000} * static_cast<int64_t>(i)) << "send " << i;
  }
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, RequestOutcome::kTimedOut);
  EXPECT_EQ(results[0].transmissions, 5);
  EXPECT_EQ(results[0].latency, 1s);
  EXPECT_EQ(results[0].completed, t0 + 1s);
  EXPECT_EQ(engine.stats().timed_out, 1u);
}

TEST_F(RequestEngineTest, AnswerOnBroadcastIdCompletesTheRequest) {
  const Micros t0 = now;
  engine.submit(read(0x761, 0x33, {0x713, 0x54}), record(), now);
  advance(t0 + 250ms);  // second transmission at 200 ms
  // Unrelated traffic, and the right function on the wrong ID, do not answer it.
  engine.on_frame(bms_status(), now);
  engine.on_frame(
      motinova::make_frame(0x720, motinova::Mode::kReport, 0x54, std::vector<uint8_t>(8, 0)), now);
  EXPECT_TRUE(results.empty());
  const AppFrame answer =
      motinova::MessageWriter(desc("mc_settings", 0x713), default_options()).frame();
  engine.on_frame(answer, now);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, RequestOutcome::kAnswered);
  EXPECT_EQ(results[0].transmissions, 2);
  EXPECT_EQ(results[0].latency, 250ms);
  ASSERT_TRUE(results[0].answered_by.has_value());
  EXPECT_EQ(*results[0].answered_by, (MessageKey{0x713, 0x54}));
  advance(t0 + 2s);
  EXPECT_EQ(sender.count(0x761, 0x33), 2u) << "no transmission after the answer";
}

TEST_F(RequestEngineTest, OneOutstandingRequestPerTargetId) {
  const Micros t0 = now;
  engine.submit(read(0x762, 0x50, {0x720, 0x10}), record(), now);
  engine.submit(read(0x762, 0x54, {0x725, 0x50}), record(), now);
  engine.submit(read(0x763, 0x70, {0x730, 0x11}), record(), now);  // another ID: not held back
  EXPECT_EQ(sender.count(0x762, 0x50), 1u);
  EXPECT_EQ(sender.count(0x762, 0x54), 0u) << "second request to 0x762 must wait";
  EXPECT_EQ(sender.count(0x763, 0x70), 1u);
  EXPECT_TRUE(engine.busy(0x762));
  EXPECT_EQ(engine.pending(0x762), 2u);

  advance(t0 + 300ms);
  EXPECT_EQ(sender.count(0x762, 0x54), 0u);
  engine.on_frame(bms_status(), now);  // answers the first: the second goes out at once
  const auto second = sender.matching(0x762, 0x54);
  ASSERT_EQ(second.size(), 1u);
  EXPECT_EQ(second[0].at, now);
  // The same frame must not also count as the answer of the request it just released.
  EXPECT_EQ(results.size(), 1u);

  advance(t0 + 5s);
  // Sequence on 0x762: 0x50 x2 (0, 200 ms), then 0x54 x5 (timeout) and nothing interleaved.
  const auto on_762 = sender.on_id(0x762);
  ASSERT_EQ(on_762.size(), 7u);
  for (std::size_t i = 0; i < on_762.size(); ++i) {
    EXPECT_EQ(on_762[i].frame.function, i < 2 ? 0x50 : 0x54) << "send " << i;
  }
}

TEST_F(RequestEngineTest, WritesGoOutOnceAndWaitForTheIdToBeFree) {
  engine.submit(read(0x767, 0x81, {0x770, 0x10}), record(), now);
  Request write;
  write.frame = keyword_frame(0x767, motinova::Mode::kWrite, 0x82, "LOCK");
  engine.submit(std::move(write), record(), now);
  EXPECT_EQ(sender.count(0x767, 0x82), 0u);
  now += 20ms;
  engine.on_frame(lock_status(0, 1), now);
  EXPECT_EQ(sender.count(0x767, 0x82), 1u);
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[1].outcome, RequestOutcome::kSent);
  EXPECT_FALSE(engine.busy(0x767));
}

TEST_F(RequestEngineTest, RefusedTransmissionIsRetriedAndCounted) {
  sender.accept = false;
  const Micros t0 = now;
  engine.submit(read(0x762, 0x50, {0x720, 0x10}), record(), now);
  advance(t0 + 250ms);
  sender.accept = true;
  EXPECT_EQ(engine.stats().send_failures, 2u);
  advance(t0 + 450ms);
  EXPECT_EQ(sender.count(0x762, 0x50), 3u);
}

TEST_F(RequestEngineTest, CancelReleasesTheIdWithoutCallback) {
  const RequestId first = engine.submit(read(0x762, 0x50, {0x720, 0x10}), record(), now);
  const RequestId second = engine.submit(read(0x762, 0x51, {0x720, 0x11}), record(), now);
  EXPECT_TRUE(engine.queued(second));
  EXPECT_FALSE(engine.queued(first));
  EXPECT_TRUE(engine.cancel(first, now));
  EXPECT_EQ(sender.count(0x762, 0x51), 1u);
  EXPECT_FALSE(engine.cancel(first, now));
  EXPECT_TRUE(results.empty());
}

TEST_F(RequestEngineTest, CallbackMaySubmitToTheSameId) {
  int chained = 0;
  engine.submit(
      read(0x762, 0x50, {0x720, 0x10}),
      [&](const RequestResult&) {
        ++chained;
        engine.submit(read(0x762, 0x51, {0x720, 0x11}), record(), now);
      },
      now);
  engine.on_frame(bms_status(), now);
  EXPECT_EQ(chained, 1);
  EXPECT_EQ(sender.count(0x762, 0x51), 1u);
  EXPECT_EQ(engine.pending(0x762), 1u);
}

}  // namespace
}  // namespace fleetgw::node::test
