// A store that refuses writes (disk full) never silences a command: the result reaches
// CommandService::take_unstored() with stored = false, nothing moves for a command that could
// not be journaled, a redelivery gets the same answer, and once the store accepts writes again
// the journal catches up without a second result. The disk is filled for real: the process's
// file-size limit (RLIMIT_FSIZE) makes SQLite's next write fail with SQLITE_FULL, on the real
// store file, exactly as a full filesystem does.
#include <sys/resource.h>

#include <csignal>

#include "gateway/command/sha256.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

// While alive, no file of this process can grow: every SQLite write fails as on a full disk.
class DiskFull {
 public:
  DiskFull() {
    previous_handler_ = std::signal(SIGXFSZ, SIG_IGN);  // EFBIG instead of being killed
    getrlimit(RLIMIT_FSIZE, &previous_);
    rlimit full = previous_;
    full.rlim_cur = 1;
    EXPECT_EQ(setrlimit(RLIMIT_FSIZE, &full), 0);
  }
  ~DiskFull() {
    setrlimit(RLIMIT_FSIZE, &previous_);
    std::signal(SIGXFSZ, previous_handler_);
  }
  DiskFull(const DiskFull&) = delete;
  DiskFull& operator=(const DiskFull&) = delete;

 private:
  rlimit previous_{};
  void (*previous_handler_)(int) = nullptr;
};

std::string command_sha_of(const std::string& signed_payload) {
  v1::SignedCommand s;
  s.ParseFromString(signed_payload);
  return sha256(s.command());
}

v1::CommandResult parse(const std::string& bytes) {
  v1::CommandResult r;
  EXPECT_TRUE(r.ParseFromString(bytes));
  return r;
}

std::size_t result_rows(storage::Store& store, std::string_view id) {
  std::size_t n = 0;
  store.export_table("command_results", 0, [&](const nlohmann::json& row) {
    if (row.value("command_id", "") == id) ++n;
  });
  return n;
}

TEST(StoreFailure, CommandThatCannotBeJournaledIsAnsweredUnstoredAndNothingMoves) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string cmd = rig.payload("seat", "unlock", "cmd-full-1");
  const Micros t0 = rig.bus.now();
  {
    DiskFull full;
    EXPECT_EQ(rig.service->on_payload(cmd, rig.bus.now()), Disposition::kRejected);
    rig.bus.run_for(3s);
    ASSERT_EQ(rig.unstored.size(), 1u);
    const auto r = parse(rig.unstored[0]);
    EXPECT_EQ(r.command_id(), "cmd-full-1");
    EXPECT_EQ(r.result(), v1::COMMAND_RESULT_CODE_REJECTED);
    EXPECT_EQ(reason_code(r), "storage_error") << r.reason();
    EXPECT_FALSE(r.stored());
    EXPECT_EQ(r.command_sha256(), command_sha_of(cmd));  // bound: the operator tool takes it
    EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
    EXPECT_EQ(rig.lock_state(0), sim::LockState::kLocked);
    EXPECT_EQ(rig.service->unjournaled(), 1u);
    // A redelivery while still full: the same answer again, still nothing on the bus.
    EXPECT_EQ(rig.service->on_payload(cmd, rig.bus.now()), Disposition::kDuplicateAnswered);
    rig.take_outputs();
    ASSERT_EQ(rig.unstored.size(), 2u);
    EXPECT_EQ(parse(rig.unstored[1]).reason(), r.reason());
    EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  }
  EXPECT_EQ(rig.stored_calls, 0);
  // Space is back: the journal catches up at a tick, with the same answer.
  rig.bus.run_for(3s);
  EXPECT_EQ(rig.service->unjournaled(), 0u);
  const auto entry = rig.store->command("cmd-full-1");
  ASSERT_TRUE(entry.has_value());
  EXPECT_EQ(entry->state, "rejected");
  EXPECT_EQ(result_rows(*rig.store, "cmd-full-1"), 1u);
  // Published directly already: nothing queued again for the uplink.
  EXPECT_EQ(rig.stored_calls, 0);
  // And a later redelivery is a duplicate of that answer, never an execution.
  const auto* again = rig.run(cmd, 2s);
  ASSERT_NE(again, nullptr);
  EXPECT_EQ(reason_code(*again), "storage_error");
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kLocked);
}

TEST(StoreFailure, ResultOfAnExecutedCommandReachesPublishUnstoredAndIsJournaledLater) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string cmd = rig.payload("seat", "unlock", "cmd-full-2");
  // Journaled while the disk has room; the disk fills while the lock moves.
  EXPECT_EQ(rig.service->on_payload(cmd, rig.bus.now()), Disposition::kStarted);
  {
    DiskFull full;
    for (int i = 0; i < 500 && rig.unstored.empty(); ++i) rig.bus.run_for(10ms);
    ASSERT_EQ(rig.unstored.size(), 1u);
    const auto r = parse(rig.unstored[0]);
    EXPECT_EQ(r.command_id(), "cmd-full-2");
    EXPECT_EQ(r.result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r.reason();
    EXPECT_FALSE(r.stored());
    EXPECT_EQ(r.command_sha256(), command_sha_of(cmd));
    EXPECT_EQ(rig.lock_state(0), sim::LockState::kUnlocked);
    EXPECT_EQ(rig.store->command("cmd-full-2")->state, "executing");
  }
  rig.bus.run_for(3s);
  EXPECT_EQ(rig.store->command("cmd-full-2")->state, "succeeded");
  // A restart now finds nothing "executing": no second, contradicting result.
  const std::size_t before = rig.results.size();
  rig.restart();
  EXPECT_EQ(rig.service->recover(rig.bus.now()), 0u);
  EXPECT_EQ(rig.results.size(), before);
}

TEST(StoreFailure, UnstoredResultTheUplinkCouldNotTakeGoesToTheOutboxLater) {
  Rig rig;
  rig.publish_unstored_ok = false;  // e.g. the broker is unreachable too
  rig.bus.run_for(2s);
  {
    DiskFull full;
    rig.service->on_payload(rig.payload("seat", "unlock", "cmd-full-3"), rig.bus.now());
    rig.take_outputs();
    ASSERT_EQ(rig.unstored.size(), 1u);
    EXPECT_EQ(rig.service->stats().unstored_not_published, 1u);
  }
  rig.bus.run_for(3s);
  EXPECT_EQ(rig.service->unjournaled(), 0u);
  EXPECT_EQ(rig.stored_calls, 1);  // queued: reported, the pipeline publishes it
  bool queued = false;
  for (const auto& e : rig.store->peek_outbox(100, 1 << 20)) {
    v1::CommandResult r;
    ASSERT_TRUE(r.ParseFromArray(e.payload.data(), static_cast<int>(e.payload.size())));
    if (r.command_id() == "cmd-full-3") {
      queued = true;
      EXPECT_TRUE(r.stored());
      EXPECT_EQ(reason_code(r), "storage_error");
    }
  }
  EXPECT_TRUE(queued);
}

TEST(StoreFailure, EachStoredResultIsReportedAsTheStagesOutput) {
  Rig rig;
  rig.bus.run_for(2s);
  const auto* ok = rig.run(rig.payload("seat", "unlock"));
  ASSERT_NE(ok, nullptr);
  EXPECT_TRUE(ok->stored());
  EXPECT_EQ(rig.stored_calls, 1);
  const auto* rejected = rig.run(rig.payload("wheel", "unlock"), 2s);  // not fitted
  ASSERT_NE(rejected, nullptr);
  EXPECT_EQ(rig.stored_calls, 2);
  rig.service->on_payload(std::string("junk"), rig.bus.now());  // outbox-only result
  rig.take_outputs();
  EXPECT_EQ(rig.stored_calls, 3);
  EXPECT_TRUE(rig.unstored.empty());
}

}  // namespace
}  // namespace fleetgw::command::testing
