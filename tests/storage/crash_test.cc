// Crash safety: a child process writes batches in a loop and reports each committed batch through
// a pipe; the parent SIGKILLs it at random moments, reopens the store and checks that the file
// is intact, that every batch whose write() returned is there, and that sequence numbers stay
// unique and gap-free across all the kills.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <random>
#include <thread>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

constexpr int kTelemetryPerBatch = 100;

// What the child reports after each write() returned: [first_seq, end_seq) and the batch index.
struct Report {
  std::uint64_t first_seq;
  std::uint64_t end_seq;
  std::uint64_t batch;
};
static_assert(sizeof(Report) < PIPE_BUF, "pipe writes below PIPE_BUF are atomic");

[[noreturn]] void child_main(const std::string& path, int round, int report_fd) {
  try {
    Store store(StoreOptions{.path = path});
    const std::string ride_id = "ride-round-" + std::to_string(round);
    for (std::uint64_t batch = 0;; ++batch) {
      Batch b;
      b.now_us = static_cast<std::int64_t>(round * 1'000'000 + batch);
      for (int i = 0; i < kTelemetryPerBatch; ++i) {
        b.telemetry.push_back({telemetry_at(b.now_us), Bytes(48, static_cast<std::uint8_t>(i))});
      }
      if (batch % 5 == 0) b.faults.push_back({fault_at(b.now_us, round), Bytes(20, 1)});
      if (batch % 7 == 0) b.packs.push_back({pack_at(b.now_us), Bytes(60, 2)});
      // The ride in progress is checkpointed every batch: distance = batch index.
      RideRow ride = ride_named(ride_id, round, false);
      ride.distance_km = static_cast<double>(batch);
      b.rides.push_back({ride, std::nullopt});
      const auto r = store.write(b);
      if (!r.ok()) _exit(4);  // a failed write: the parent reports the early exit
      Report rep{r->first_seq, r->end_seq, batch};
      if (::write(report_fd, &rep, sizeof rep) != static_cast<ssize_t>(sizeof rep)) _exit(3);
    }
  } catch (...) {
    _exit(2);
  }
}

TEST(CrashSafety, SigkillAtRandomMomentsLosesNoCommittedBatch) {
  TempDir dir;
  const std::string path = dir.file("crash.db");
  const auto seed =
      static_cast<unsigned>(std::chrono::steady_clock::now().time_since_epoch().count());
  std::mt19937 rng(seed);
  SCOPED_TRACE("random seed " + std::to_string(seed));
  std::uniform_int_distribution<int> delay_ms(40, 400);

  std::uint64_t total_reported = 0;
  // Ten rounds, and more (up to 60) until the children have committed enough batches to test
  // anything: a slow machine (qemu emulation under load) may spend a short round opening the store.
  for (int round = 0; round < 10 || (total_reported <= 10 && round < 60); ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    std::array<int, 2> fds{};
    ASSERT_EQ(::pipe(fds.data()), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      child_main(path, round, fds[1]);
    }
    ::close(fds[1]);
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms(rng)));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status)) << "child exited early with status " << WEXITSTATUS(status);

    std::vector<Report> reports;
    Report rep{};
    while (::read(fds[0], &rep, sizeof rep) == static_cast<ssize_t>(sizeof rep)) {
      reports.push_back(rep);
    }
    ::close(fds[0]);
    total_reported += reports.size();

    Store store(StoreOptions{.path = path});
    ASSERT_EQ(store.integrity_check(), "ok");
    ASSERT_FALSE(store.moved_aside_path().has_value()) << "a kill must never look like corruption";

    Database raw(path);
    // Gap-free and unique: the outbox (never acked here) holds exactly 1..next_seq-1.
    const auto last = static_cast<std::int64_t>(store.next_seq()) - 1;
    EXPECT_EQ(raw.query_int64("SELECT count(*) FROM outbox"), last);
    EXPECT_EQ(raw.query_int64("SELECT count(DISTINCT seq) FROM outbox"), last);
    EXPECT_EQ(raw.query_int64("SELECT ifnull(min(seq), 1) FROM outbox"), 1);
    EXPECT_EQ(raw.query_int64("SELECT ifnull(max(seq), 0) FROM outbox"), last);
    EXPECT_EQ(raw.query_text("SELECT value FROM meta WHERE key = 'storage.next_seq'").value_or("1"),
              std::to_string(last + 1));

    // Every batch whose write() returned before the kill is on disk.
    for (const Report& r : reports) {
      ASSERT_LT(r.first_seq, r.end_seq);
      ASSERT_LE(static_cast<std::int64_t>(r.end_seq) - 1, last) << "batch " << r.batch;
      Statement st = raw.prepare("SELECT count(*) FROM outbox WHERE seq >= ? AND seq < ?");
      st.bind_all(static_cast<std::int64_t>(r.first_seq), static_cast<std::int64_t>(r.end_seq));
      ASSERT_TRUE(st.step());
      ASSERT_EQ(static_cast<std::uint64_t>(st.column_int64(0)), r.end_seq - r.first_seq);
    }
    if (!reports.empty()) {
      // The ride checkpoint is at least as new as the last reported batch (one more batch may
      // have committed between its write() returning and the report reaching the pipe).
      auto ride = store.ride("ride-round-" + std::to_string(round));
      ASSERT_TRUE(ride.has_value());
      EXPECT_GE(ride->distance_km, static_cast<double>(reports.back().batch));
      EXPECT_LE(ride->distance_km, static_cast<double>(reports.back().batch + 1));
      const auto telemetry = raw.query_int64("SELECT count(*) FROM telemetry").value_or(0);
      EXPECT_GE(telemetry, static_cast<std::int64_t>(reports.size()) * kTelemetryPerBatch);
    }
  }
  EXPECT_GT(total_reported, 10u) << "the child must have committed batches to test anything";
}

}  // namespace
}  // namespace fleetgw::storage
