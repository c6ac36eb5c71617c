// LockActuator: LOCK/UNLOCK write, status polling every 200 ms, success, failure (5/6),
// timeout, one command per lock.
#include <gtest/gtest.h>

#include "fake_bus.h"

namespace fleetgw::node::test {
namespace {

NodeConfig lock_config() {
  NodeConfig cfg = quiet_config();
  cfg.fitted_locks = {true, false, false, true, false};
  return cfg;
}

struct LockTest : ::testing::Test {
  FakeBus bus{lock_config()};
  std::vector<LockResult> results;
  Micros t0{};
  void SetUp() override {
    t0 = bus.now;
    bus.start();
  }
  LockActuator::Callback record() {
    return [this](const LockResult& r) { results.push_back(r); };
  }
  // The lock answers every status read (F+1) 20 ms later with the state `script` gives for the
  // number of reads so far.
  void answer_reads(int k, std::function<uint8_t(int)> script) {
    bus.responder = [k, script, reads = 0](const AppFrame& sent, FakeBus& b) mutable {
      if (sent.can_id == ids::lock_command_id(k) &&
          sent.function == ids::lock_function_base(k) + 1) {
        b.at(b.now + 20ms, lock_status(k, script(++reads)));
      }
    };
  }
};

TEST_F(LockTest, LockSucceedsWhenStatusReachesLocked) {
  answer_reads(0, [](int read) { return read < 2 ? lock_state::kLocking : lock_state::kLocked; });
  ASSERT_EQ(bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, record()), LockStart::kStarted);
  // Spec test vector T3: 0x767 write 0x8204 "LOCK".
  const auto cmd = bus.sender.matching(0x767, 0x82);
  ASSERT_EQ(cmd.size(), 1u);
  EXPECT_EQ(cmd[0].frame.mode, motinova::Mode::kWrite);
  EXPECT_TRUE(is_keyword(cmd[0].frame, "LOCK"));
  const auto wire = motinova::encode_frame(cmd[0].frame);
  const std::vector<uint8_t> t3{0x55, 0xAA, 0x16, 0x06, 0x82, 0x04, 0x4C, 0x4F,
                                0x43, 0x4B, 0xE5, 0xC4, 0x61, 0x3B, 0xF0};
  EXPECT_EQ(std::vector<uint8_t>(wire.begin(), wire.end()), t3);

  bus.run_until(t0 + 3s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kSucceeded);
  EXPECT_EQ(results[0].final_state, lock_state::kLocked);
  EXPECT_EQ(results[0].elapsed, 420ms);  // reads at 200 (-> locking) and 400 (-> locked) + 20
  EXPECT_EQ(results[0].commands_sent, 1) << "the lock reacted: no repeat of the command";
  const auto reads = bus.sender.matching(0x767, 0x81);
  ASSERT_EQ(reads.size(), 2u);
  EXPECT_EQ(reads[0].at - t0, 200ms);
  EXPECT_EQ(reads[1].at - t0, 400ms);
  EXPECT_FALSE(bus.node->locks().busy(0));
}

TEST_F(LockTest, UnlockConfirmedByBroadcastWithoutWaitingForTheRead) {
  ASSERT_EQ(bus.node->actuate_lock(3, LockTarget::kUnlocked, bus.now, record()),
            LockStart::kStarted);
  const auto cmd = bus.sender.matching(0x76A, 0xB3);  // LOCK 4: F = 0xB0, UNLOCK = F+3
  ASSERT_EQ(cmd.size(), 1u);
  EXPECT_TRUE(is_keyword(cmd[0].frame, "UNLOCK"));
  bus.at(t0 + 90ms, lock_status(3, lock_state::kUnlocked));  // 0x7A0 cyclic broadcast
  bus.run_until(t0 + 1s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kSucceeded);
  EXPECT_EQ(results[0].elapsed, 90ms);
  EXPECT_EQ(bus.sender.count(0x76A, 0xB1), 0u) << "confirmed before the first status read";
}

TEST_F(LockTest, LockFailureState6IsReported) {
  answer_reads(0, [](int) { return lock_state::kLockFailed; });
  bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, record());
  bus.run_until(t0 + 3s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kFailed);
  EXPECT_EQ(results[0].final_state, 6);
  EXPECT_EQ(results[0].elapsed, 220ms);
}

TEST_F(LockTest, UnlockFailureState5IsReportedButState6IsNotAnUnlockFailure) {
  answer_reads(
      0, [](int read) { return read == 1 ? lock_state::kLockFailed : lock_state::kUnlockFailed; });
  bus.node->actuate_lock(0, LockTarget::kUnlocked, bus.now, record());
  bus.run_until(t0 + 3s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kFailed);
  EXPECT_EQ(results[0].final_state, 5);
  EXPECT_EQ(results[0].elapsed, 420ms);
}

TEST_F(LockTest, StaleFailureFromAnEarlierAttemptIsIgnored) {
  bus.deliver(lock_status(0, lock_state::kLockFailed));  // before the command
  answer_reads(0, [](int read) {
    if (read <= 2) return lock_state::kLockFailed;  // still the old failure
    if (read == 3) return lock_state::kLocking;
    return lock_state::kLockFailed;  // a fresh failure
  });
  bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, record());
  bus.run_until(t0 + 3s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kFailed);
  EXPECT_EQ(results[0].elapsed, 820ms);  // fourth read at 800 ms
}

TEST_F(LockTest, SilentLockTimesOutAfter3sWithCommandRepeats) {
  bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, record());
  bus.run_until(t0 + 5s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kTimeout);
  EXPECT_FALSE(results[0].final_state.has_value());
  EXPECT_EQ(results[0].elapsed, 3s);
  // No reaction: the command is repeated (0, 600, 1200 ms), 3 transmissions in all.
  EXPECT_EQ(results[0].commands_sent, 3);
  const auto cmds = bus.sender.matching(0x767, 0x82);
  ASSERT_EQ(cmds.size(), 3u);
  // Status reads every 200 ms from 200 ms until the timeout, nothing after it.
  const auto reads = bus.sender.matching(0x767, 0x81);
  EXPECT_EQ(reads.front().at - t0, 200ms);
  EXPECT_LT(reads.back().at - t0, 3s);
  for (std::size_t i = 1; i < reads.size(); ++i) EXPECT_EQ(reads[i].at - reads[i - 1].at, 200ms);
  EXPECT_EQ(reads.size(), 14u);
}

TEST_F(LockTest, CallbackMayStartTheNextCommandOnTheSameLock) {
  LockStart second = LockStart::kBadIndex;
  bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, [&](const LockResult& r) {
    results.push_back(r);
    second = bus.node->actuate_lock(0, LockTarget::kUnlocked, bus.now, record());
  });
  bus.at(t0 + 50ms, lock_status(0, lock_state::kLocked));
  bus.run_until(t0 + 100ms);
  EXPECT_EQ(second, LockStart::kStarted);
  EXPECT_EQ(bus.sender.count(0x767, 0x83), 1u);
}

TEST_F(LockTest, CustomTimeout) {
  bus.node->actuate_lock(0, LockTarget::kUnlocked, bus.now, record(), 1s);
  bus.run_until(t0 + 2s);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].outcome, LockOutcome::kTimeout);
  EXPECT_EQ(results[0].elapsed, 1s);
}

TEST_F(LockTest, SecondCommandOnABusyLockIsRefused) {
  EXPECT_EQ(bus.node->actuate_lock(0, LockTarget::kLocked, bus.now, record()), LockStart::kStarted);
  EXPECT_EQ(bus.node->actuate_lock(0, LockTarget::kUnlocked, bus.now, record()), LockStart::kBusy);
  EXPECT_EQ(bus.node->actuate_lock(1, LockTarget::kLocked, bus.now, record()),
            LockStart::kNotFitted);
  EXPECT_EQ(bus.node->actuate_lock(5, LockTarget::kLocked, bus.now, record()),
            LockStart::kBadIndex);
  EXPECT_EQ(bus.node->actuate_lock(3, LockTarget::kLocked, bus.now, record()), LockStart::kStarted)
      << "other locks are independent";
  EXPECT_EQ(bus.sender.count(0x767, 0x83), 0u) << "the refused UNLOCK never reached the bus";
  bus.at(t0 + 50ms, lock_status(0, lock_state::kLocked));
  bus.run_until(t0 + 100ms);
  // Once done, the lock accepts the next command.
  EXPECT_EQ(bus.node->actuate_lock(0, LockTarget::kUnlocked, bus.now, record()),
            LockStart::kStarted);
}

TEST_F(LockTest, CommandQueuesBehindAnOutstandingStatusPoll) {
  NodeConfig cfg = lock_config();
  cfg.poll_table = {PollEntry{"lock1_status", 0x767, 0x8100, {{0x770, 0x10}}, 1s}};
  cfg.requests.startup_grace = 0s;
  FakeBus b(cfg);
  b.start();  // the status poll goes out at once and stays outstanding
  ASSERT_EQ(b.sender.count(0x767, 0x81), 1u);
  b.node->actuate_lock(0, LockTarget::kLocked, b.now, record());
  EXPECT_EQ(b.sender.count(0x767, 0x82), 0u) << "waits: one request per ID";
  b.run_for(30ms);
  b.deliver(lock_status(0, lock_state::kUnlocked));  // answers the poll
  EXPECT_EQ(b.sender.count(0x767, 0x82), 1u);
}

}  // namespace
}  // namespace fleetgw::node::test
