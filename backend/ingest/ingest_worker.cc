// The ingest worker (ingest_worker.h): its MQTT sessions, the batch loop, PostgreSQL.
#include "backend/ingest/ingest_worker.h"

#include <fmt/format.h>
#include <malloc.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <variant>
#include <vector>

#include "backend/ingest/envelope_rows.h"
#include "backend/ingest/ingest_store.h"
#include "backend/ingest/mqtt_sessions.h"
#include "backend/ingest/safe_text.h"

namespace fleetgw::ingest {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

struct Counters {
  std::int64_t messages = 0;
  std::int64_t records = 0;
  std::int64_t batches = 0;
  WriteStats rows;
  std::map<std::string, std::int64_t> rejected;  // by reason code
};

std::string summary(const Counters& c) {
  std::string rejects;
  std::int64_t total = 0;
  for (const auto& [code, n] : c.rejected) {
    rejects += fmt::format("{}{}={}", rejects.empty() ? "" : ",", code, n);
    total += n;
  }
  return fmt::format(
      "ingest: {} messages, {} records, {} rows inserted, {} duplicates ignored, {} rejected{}, "
      "{} out-of-order states ignored, {} batches",
      c.messages, c.records, c.rows.inserted, c.rows.duplicates, total,
      rejects.empty() ? "" : " (" + rejects + ")", c.rows.stale_states, c.batches);
}

std::string default_client_id(const std::string& group) {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return group + "-" + (host[0] != '\0' ? host : "worker");
}

// A received message waiting for its batch to commit.
struct Item {
  std::size_t session;
  std::string topic;
  std::size_t bytes;
  std::variant<Decoded, Reject> decoded;
};

// After a message larger than this, freed memory is given back to the system (malloc_trim).
constexpr std::size_t kLargeMessageBytes = 64 * 1024;

// A batch also closes at this many payload bytes: with the rows bound, what bounds its memory.
constexpr std::size_t kBatchMaxBytes = 32 * 1024 * 1024;

std::optional<BatchPoint> crash_point() {
  const char* at = std::getenv("FLEETGW_INGEST_CRASH_AT");
  const std::string_view v = at != nullptr ? at : "";
  if (v == "before_copy") return BatchPoint::kBeforeCopy;
  if (v == "after_copy") return BatchPoint::kAfterCopy;
  if (v == "after_commit") return BatchPoint::kAfterCommit;
  return std::nullopt;
}

// A batch handed to the database thread, and what came of it.
struct Job {
  std::uint64_t generation = 0;  // its sessions' seal (MqttSessions::seal)
  std::vector<Item> items;
  bool large = false;
  // Results, set by the database thread.
  bool committed = false;  // false: given up at a stop while PostgreSQL refused it
  WriteStats stats;
  std::int64_t records = 0;
  std::vector<RejectRow> rejects;  // decoder's and database's, stored (topics point into items)
};

// The database thread: writes one Job at a time, retrying a transient failure with back-off
// (100 ms .. 5 s) until it commits or the worker gives it up at a stop. Meanwhile the loop
// reads the next batch from the sessions this one does not hold (mqtt_sessions.h, seal()).
class Writer {
 public:
  Writer(IngestStore& store, const IngestOptions& o) : store_(store), o_(o) {
    done_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (const auto point = crash_point()) {
      const char* n = std::getenv("FLEETGW_INGEST_CRASH_BATCH");
      const long crash_batch = n != nullptr ? std::max(1L, std::atol(n)) : 1;
      store_.set_batch_hook([this, point, crash_batch](BatchPoint p) {
        if (p == *point && record_batches_ == crash_batch) ::kill(::getpid(), SIGKILL);
      });
    }
    thread_ = std::thread([this] { loop(); });
  }
  ~Writer() {
    {
      std::lock_guard lock(mu_);
      quit_ = true;
      abort_ = true;
    }
    cv_.notify_all();
    thread_.join();
    ::close(done_fd_);
  }
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  int done_fd() const { return done_fd_; }
  bool busy() const { return busy_; }  // loop thread only
  void submit(std::unique_ptr<Job> job) {
    busy_ = true;
    {
      std::lock_guard lock(mu_);
      job_ = std::move(job);
    }
    cv_.notify_all();
  }
  // The finished job, once done_fd() was readable (nullptr: not finished yet).
  std::unique_ptr<Job> take() {
    std::uint64_t n = 0;
    [[maybe_unused]] const auto r = ::read(done_fd_, &n, sizeof n);
    std::lock_guard lock(mu_);
    if (!done_) return nullptr;
    busy_ = false;
    return std::move(done_);
  }
  // At a stop: a job PostgreSQL keeps refusing is given up (not committed, not acknowledged).
  void abort_retries() {
    {
      std::lock_guard lock(mu_);
      abort_ = true;
    }
    cv_.notify_all();
  }
  bool failing() const { return failing_.load(); }
  void request_maintenance() {
    {
      std::lock_guard lock(mu_);
      maintain_ = true;
    }
    cv_.notify_all();
  }
  void maintain() {
    try {
      const int dropped = store_.maintain_partitions(o_.partition_days_ahead, o_.retention_days);
      if (dropped > 0) spdlog::info("ingest: dropped {} telemetry partition(s)", dropped);
    } catch (const PgError& e) {
      spdlog::warn("ingest: telemetry partitions: {}", e.what());
    }
  }

 private:
  void loop() {
    std::unique_lock lock(mu_);
    for (;;) {
      cv_.wait(lock, [&] { return quit_ || job_ != nullptr || maintain_; });
      if (job_ != nullptr) {
        std::unique_ptr<Job> job = std::move(job_);
        lock.unlock();
        write(*job);
        lock.lock();
        done_ = std::move(job);
        const std::uint64_t one = 1;
        [[maybe_unused]] const auto r = ::write(done_fd_, &one, sizeof one);
      } else if (maintain_) {
        maintain_ = false;
        lock.unlock();
        maintain();
        lock.lock();
      } else if (quit_) {
        return;
      }
    }
  }

  void write(Job& job) {
    std::vector<const Decoded*> messages;
    std::vector<std::size_t> message_items;
    std::vector<RejectRow> rejects;
    std::int64_t records = 0;
    for (std::size_t i = 0; i < job.items.size(); ++i) {
      const Item& it = job.items[i];
      if (const auto* d = std::get_if<Decoded>(&it.decoded)) {
        messages.push_back(d);
        message_items.push_back(i);
        records += static_cast<std::int64_t>(d->records);
      } else {
        rejects.push_back({it.topic, std::get<Reject>(it.decoded), it.bytes});
      }
    }
    if (records > 0) ++record_batches_;
    auto backoff = std::chrono::milliseconds(100);
    for (;;) {
      try {
        const auto started = Clock::now();
        const BatchResult r = store_.write_batch(messages, rejects);
        spdlog::debug(
            "ingest: batch of {} messages in {} ms", job.items.size(),
            std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - started).count());
        std::vector<RejectRow> refused;
        for (std::size_t m = 0; m < messages.size(); ++m) {
          if (!r.refused[m]) continue;
          const Item& it = job.items[message_items[m]];
          refused.push_back({it.topic, *r.refused[m], it.bytes});
          records -= static_cast<std::int64_t>(messages[m]->records);
        }
        if (!refused.empty()) store_.write_batch({}, refused);
        if (failing_) spdlog::info("ingest: PostgreSQL writes succeed again");
        failing_ = false;
        job.stats = r.stats;
        job.records = records;
        rejects.insert(rejects.end(), refused.begin(), refused.end());
        job.rejects = std::move(rejects);
        job.committed = true;
        return;
      } catch (const PgError& e) {
        if (!is_transient(e)) {
          // Only the rejected-message rows can fail so: the messages cannot be stored anyway.
          spdlog::error("ingest: could not record rejected messages: {}", e.what());
          job.committed = true;
          return;
        }
        if (!failing_) {
          spdlog::warn("ingest: {} (the batch's {} message(s) stay unacknowledged; retrying)",
                       e.what(), job.items.size());
        }
        failing_ = true;
      }
      std::unique_lock lock(mu_);
      if (cv_.wait_for(lock, backoff, [&] { return abort_; })) return;  // not committed
      backoff = std::min(backoff * 2, std::chrono::milliseconds(5000));
    }
  }

  IngestStore& store_;
  const IngestOptions& o_;
  int done_fd_ = -1;
  bool busy_ = false;  // loop thread only
  std::atomic<bool> failing_{false};
  long record_batches_ = 0;  // database thread only (and its crash hook)
  std::mutex mu_;
  std::condition_variable cv_;
  std::unique_ptr<Job> job_;   // submitted, not yet taken by the database thread
  std::unique_ptr<Job> done_;  // finished, not yet taken by the loop
  bool maintain_ = false;
  bool abort_ = false;
  bool quit_ = false;
  std::thread thread_;  // last: started once every member above is ready
};

class Worker {
 public:
  Worker(const IngestOptions& o, IngestStore& store, const std::string& client_id, int sigfd)
      : o_(o),
        sessions_(o, client_id,
                  [this](std::size_t i, std::string_view topic, std::string_view payload) {
                    add(i, topic, payload);
                  }),
        sigfd_(sigfd),
        writer_(store, o) {}

  bool connect(std::string& error) {
    if (o_.leave) start_leave();
    return sessions_.connect(error);
  }

  int run(const std::string& client_id, const std::string& filter) {
    const auto start = Clock::now();
    auto next_report = start + 60s;
    auto next_maintenance = start + 1h;
    bool announced = false;
    int status = 0;
    bool given_up = false;
    const auto k = static_cast<long>(sessions_.size());
    const int fds[] = {sigfd_, writer_.done_fd()};
    for (;;) {
      const auto now = Clock::now();
      // Reading stops while the batch being filled is full (the one being written holds its
      // own sessions sealed): the broker keeps the rest, at most two batches are in memory.
      const bool reading = !stopping_ && !full();
      auto wake = now + 200ms;
      if (!batch_.empty() && !writer_.busy()) wake = std::min(wake, first_at_ + delay());
      const auto timeout = std::chrono::duration_cast<std::chrono::milliseconds>(wake - now);
      const unsigned ready =
          sessions_.poll(std::max(timeout, 0ms), fds, reading, [this] { return !full(); });
      if ((ready & 1u) != 0) {
        signalfd_siginfo info{};
        while (::read(sigfd_, &info, sizeof info) == sizeof info) {
          if (info.ssi_signo == SIGINT || info.ssi_signo == SIGTERM) stopping_ = true;
          if (info.ssi_signo == SIGUSR1 && !stopping_ && !leaving_) start_leave();
        }
      }
      if ((ready & 2u) != 0) {
        if (std::unique_ptr<Job> job = writer_.take()) {
          if (!finish(*job)) given_up = true;
        }
      }
      if (leaving_ && !stopping_ && left()) stopping_ = true;
      if (!announced && !leaving_ && sessions_.subscribed() == sessions_.size()) {
        announced = true;
        const auto resumed = static_cast<long>(sessions_.resumed());
        spdlog::info(
            "ingest: connected to {} as {}-s1..s{} ({} sessions of {} in-flight messages, {}), "
            "subscribed to {}",
            o_.broker, client_id, k, k, o_.inflight,
            resumed == k   ? "session resumed"
            : resumed == 0 ? "session new"
                           : fmt::format("{} of {} sessions resumed", resumed, k),
            filter);
      }
      if (const std::string refused = sessions_.refused(); !refused.empty() && !stopping_) {
        spdlog::error("ingest: the broker refused {}; stopping", refused);
        status = 1;
        stopping_ = true;
      }
      if (!given_up && should_hand_off(Clock::now())) hand_off();
      if (!stopping_ && o_.duration_s > 0 &&
          Clock::now() - start >= std::chrono::duration<double>(o_.duration_s)) {
        stopping_ = true;
      }
      if (Clock::now() >= next_report) {
        spdlog::info("{}", summary(counters_));
        next_report += 60s;
      }
      if (Clock::now() >= next_maintenance) {
        next_maintenance += 1h;
        writer_.request_maintenance();
      }
      if (stopping_) {
        // A batch PostgreSQL keeps refusing is given up: its messages, and those of the batch
        // being filled, are left to the broker (nothing of them acknowledged).
        if (writer_.busy() && writer_.failing()) writer_.abort_retries();
        if (!writer_.busy() && (batch_.empty() || given_up)) break;
      }
    }
    const bool committed = batch_.empty() && !given_up;
    not_committed_ += static_cast<std::int64_t>(batch_.size());
    const bool forget = committed && leaving_ && left();
    sessions_.close(committed, forget);
    if (forget) {
      spdlog::info(
          "ingest: left group {} for good: {} message(s) drained from {}-s1..s{} and committed; "
          "the broker forgot the sessions",
          o_.group, counters_.messages - messages_at_leave_, client_id, k);
      // A mistyped --client-id makes a leave of sessions that never were: say so (a leave run
      // again after it finished finds none either).
      if (const auto present = static_cast<long>(sessions_.resumed()); o_.leave && present < k) {
        spdlog::warn(
            "ingest: only {} of the {} sessions {}-s1..s{} were on the broker (a wrong "
            "--client-id or --sessions, or a leave that had finished?)",
            present, k, client_id, k);
      }
    } else if (leaving_) {
      spdlog::warn(
          "ingest: the leave of {}-s1..s{} did not finish: the sessions stay on the broker "
          "(unsubscribed, if the broker confirmed it); run fleetgw ingest --leave again",
          client_id, k);
      if (status == 0) status = 3;
    }
    if (not_committed_ > 0) {
      spdlog::warn(
          "ingest: stopped with {} uncommitted message(s): not acknowledged, the broker "
          "delivers them again",
          not_committed_);
      if (status == 0) status = 3;
    }
    std::cerr << summary(counters_) << '\n';
    return status;
  }

  void maintain() { writer_.maintain(); }

 private:
  std::chrono::milliseconds delay() const { return std::chrono::milliseconds(o_.batch_delay_ms); }

  // Leaving the group for good (--leave, SIGUSR1; docs/backend.md "Leaving for good"): the
  // sessions unsubscribe and drain what the broker queued for them through the usual batches;
  // once every one is drained the worker stops and its sessions end with session expiry 0.
  void start_leave() {
    leaving_ = true;
    messages_at_leave_ = counters_.messages;
    sessions_.leave();
    spdlog::info("ingest: leaving group {}: unsubscribing, draining what the broker holds",
                 o_.group);
  }
  bool left() const {
    return sessions_.drained() == sessions_.size() && batch_.empty() && !writer_.busy();
  }

  bool full() const { return rows_ >= o_.batch_rows || bytes_ >= kBatchMaxBytes; }

  void add(std::size_t session, std::string_view topic, std::string_view payload) {
    if (batch_.empty()) first_at_ = Clock::now();
    Item item{session, std::string(topic), payload.size(),
              decode_message(o_.topic_prefix, topic, payload)};
    if (const auto* d = std::get_if<Decoded>(&item.decoded)) {
      for (const RowSet& r : d->rows) rows_ += r.rows();
    }
    bytes_ += payload.size() + topic.size();
    large_ = large_ || payload.size() > kLargeMessageBytes;
    batch_.push_back(std::move(item));
  }

  bool should_hand_off(Clock::time_point now) const {
    if (batch_.empty() || writer_.busy()) return false;
    // Every session sealed or at its receive maximum: nothing more can arrive.
    return stopping_ || full() || sessions_.saturated() || now >= first_at_ + delay();
  }

  void hand_off() {
    auto job = std::make_unique<Job>();
    job->generation = ++generation_;
    // The sessions holding this batch's messages: not read again until it is committed.
    sessions_.seal(job->generation);
    job->items = std::move(batch_);
    job->large = large_;
    batch_ = {};
    rows_ = 0;
    bytes_ = 0;
    large_ = false;
    writer_.submit(std::move(job));
  }

  // A job back from the database thread; false when it was given up (not committed).
  bool finish(Job& job) {
    if (!job.committed) {
      not_committed_ += static_cast<std::int64_t>(job.items.size());
      return false;
    }
    counters_.rows += job.stats;
    counters_.records += job.records;
    ++counters_.batches;
    for (const RejectRow& rr : job.rejects) log_reject(rr);
    counters_.messages += static_cast<std::int64_t>(job.items.size());
    // The PUBACKs of exactly this batch's messages go now.
    sessions_.acknowledge(job.generation);
    if (job.large) {
      job.items.clear();
      job.items.shrink_to_fit();
      ::malloc_trim(0);
    }
    return true;
  }

  void log_reject(const RejectRow& r) {
    const bool first = ++counters_.rejected[r.reject.code] == 1;
    const std::string where = untrusted_excerpt(r.topic, 200);
    if (first) {
      spdlog::warn(
          "ingest: rejected a message on {}: {} ({}; later ones with this reason are "
          "counted, not logged)",
          where, r.reject.detail, r.reject.code);
    } else {
      spdlog::debug("ingest: rejected a message on {}: {} ({})", where, r.reject.detail,
                    r.reject.code);
    }
  }

  const IngestOptions& o_;
  MqttSessions sessions_;
  int sigfd_;
  std::vector<Item> batch_;  // being filled
  std::size_t rows_ = 0;
  std::size_t bytes_ = 0;
  bool large_ = false;
  Clock::time_point first_at_{};
  bool stopping_ = false;
  bool leaving_ = false;
  std::int64_t messages_at_leave_ = 0;
  std::uint64_t generation_ = 0;
  std::int64_t not_committed_ = 0;
  Counters counters_;
  Writer writer_;  // last: its thread stops (joined) before the members above go
};

int print_gaps(IngestStore& store) {
  const std::vector<Gap> gaps = store.gaps();
  for (const Gap& g : gaps) {
    std::cout << fmt::format("{}\t{}\t{}..{}\n", g.vehicle_id, g.store_id, g.first_missing,
                             g.last_missing);
  }
  std::cerr << fmt::format("ingest: {} gap{}\n", gaps.size(), gaps.size() == 1 ? "" : "s");
  return gaps.empty() ? 0 : 1;
}

}  // namespace

int run_ingest(const IngestOptions& o) {
  if (o.pg.empty()) {
    std::cerr << "fleetgw ingest: --pg CONNINFO is required\n";
    return 2;
  }
  // Stop signals are read from a signalfd (no handler runs anywhere), blocked from the start
  // (before the migrations, which may take a while): a SIGTERM then is a clean stop, not a
  // death. Every thread started later inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGUSR1);  // leave the group for good (Worker::start_leave)
  if (!o.gaps) ::sigprocmask(SIG_BLOCK, &signals, nullptr);
  IngestStore store(o.pg);
  try {
    const int applied = store.connect();
    if (applied > 0) spdlog::info("ingest: applied {} schema migration(s)", applied);
  } catch (const PgError& e) {
    std::cerr << "fleetgw ingest: " << e.what() << '\n';
    return 1;
  }
  if (o.gaps) return print_gaps(store);

  const int sigfd = ::signalfd(-1, &signals, SFD_NONBLOCK | SFD_CLOEXEC);

  const std::string client_id = o.client_id.empty() ? default_client_id(o.group) : o.client_id;
  const std::string filter = "$share/" + o.group + "/" + o.topic_prefix + "/#";
  int status = 1;
  {
    Worker worker(o, store, client_id, sigfd);
    std::string error;
    if (!worker.connect(error)) {
      std::cerr << "fleetgw ingest: " << error << '\n';
    } else {
      worker.maintain();
      status = worker.run(client_id, filter);
    }
  }
  ::close(sigfd);
  return status;
}

}  // namespace fleetgw::ingest
