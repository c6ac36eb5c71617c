// The ingest worker (ingest_worker.h): its MQTT sessions, the batch loop, PostgreSQL.
#include "backend/ingest/ingest_worker.h"

#include <fmt/format.h>
#include <malloc.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <iostream>
#include <map>
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

class Worker {
 public:
  Worker(const IngestOptions& o, IngestStore& store, const std::string& client_id, int sigfd)
      : o_(o),
        store_(store),
        sessions_(o, client_id,
                  [this](std::size_t i, std::string_view topic, std::string_view payload) {
                    add(i, topic, payload);
                  }),
        sigfd_(sigfd) {
    if (const auto point = crash_point()) {
      const char* n = std::getenv("FLEETGW_INGEST_CRASH_BATCH");
      const long crash_batch = n != nullptr ? std::max(1L, std::atol(n)) : 1;
      store_.set_batch_hook([this, point, crash_batch](BatchPoint p) {
        if (p == *point && record_batches_ == crash_batch) ::kill(::getpid(), SIGKILL);
      });
    }
  }

  bool connect(std::string& error) { return sessions_.connect(error); }

  int run(const std::string& client_id, const std::string& filter) {
    const auto start = Clock::now();
    auto next_report = start + 60s;
    auto next_maintenance = start + 1h;
    bool announced = false;
    int status = 0;
    const auto k = static_cast<long>(sessions_.size());
    for (;;) {
      const auto now = Clock::now();
      // No message is read while a batch waits for PostgreSQL or is full: the broker keeps
      // the rest (back-pressure), memory stays bounded.
      const bool reading = !stopping_ && !retrying_ && !full();
      auto wake = now + 200ms;
      if (!batch_.empty()) wake = std::min(wake, std::max(retry_at_, first_at_ + delay()));
      const auto timeout = std::chrono::duration_cast<std::chrono::milliseconds>(wake - now);
      if (sessions_.poll(std::max(timeout, 0ms), sigfd_, reading, [this] { return !full(); })) {
        signalfd_siginfo info{};
        while (::read(sigfd_, &info, sizeof info) == sizeof info) {
          if (info.ssi_signo == SIGINT || info.ssi_signo == SIGTERM) stopping_ = true;
        }
      }
      if (!announced && sessions_.subscribed() == sessions_.size()) {
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
      if (should_flush(Clock::now())) flush();
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
        maintain();
      }
      // Stopping: once the batch in hand is committed, or at once while PostgreSQL refuses
      // it (its messages are left to the broker: nothing of them was acknowledged).
      if (stopping_ && (batch_.empty() || retrying_)) break;
    }
    const bool committed = batch_.empty();
    not_committed_ += static_cast<std::int64_t>(batch_.size());
    sessions_.close(committed);
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

  void maintain() {
    try {
      const int dropped = store_.maintain_partitions(o_.partition_days_ahead, o_.retention_days);
      if (dropped > 0) spdlog::info("ingest: dropped {} telemetry partition(s)", dropped);
    } catch (const PgError& e) {
      spdlog::warn("ingest: telemetry partitions: {}", e.what());
    }
  }

 private:
  std::chrono::milliseconds delay() const { return std::chrono::milliseconds(o_.batch_delay_ms); }

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

  bool should_flush(Clock::time_point now) const {
    if (batch_.empty() || now < retry_at_) return false;
    // Every session at its receive maximum: nothing more can arrive before this commits.
    const bool capped = sessions_.held() >= sessions_.size() * o_.inflight;
    return stopping_ || full() || capped || now >= first_at_ + delay();
  }

  void flush() {
    std::vector<const Decoded*> messages;
    std::vector<std::size_t> message_items;
    std::vector<RejectRow> rejects;
    std::int64_t records = 0;
    for (std::size_t i = 0; i < batch_.size(); ++i) {
      const Item& it = batch_[i];
      if (const auto* d = std::get_if<Decoded>(&it.decoded)) {
        messages.push_back(d);
        message_items.push_back(i);
        records += static_cast<std::int64_t>(d->records);
      } else {
        rejects.push_back({it.topic, std::get<Reject>(it.decoded), it.bytes});
      }
    }
    if (records > 0 && !retrying_) ++record_batches_;
    try {
      const auto started = Clock::now();
      const BatchResult r = store_.write_batch(messages, rejects);
      spdlog::debug(
          "ingest: batch of {} messages, {} rows in {} ms", batch_.size(), rows_,
          std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - started).count());
      std::vector<RejectRow> refused;
      for (std::size_t m = 0; m < messages.size(); ++m) {
        if (!r.refused[m]) continue;
        const Item& it = batch_[message_items[m]];
        refused.push_back({it.topic, *r.refused[m], it.bytes});
        records -= static_cast<std::int64_t>(messages[m]->records);
      }
      if (!refused.empty()) store_.write_batch({}, refused);
      if (db_failing_) spdlog::info("ingest: PostgreSQL writes succeed again");
      db_failing_ = false;
      counters_.rows += r.stats;
      counters_.records += records;
      ++counters_.batches;
      rejects.insert(rejects.end(), refused.begin(), refused.end());
      for (const RejectRow& rr : rejects) log_reject(rr);
    } catch (const PgError& e) {
      if (is_transient(e)) {
        retry_later(e);
        return;
      }
      // Only the rejected-message rows can fail so: the messages cannot be stored anyway.
      spdlog::error("ingest: could not record rejected messages: {}", e.what());
    }
    counters_.messages += static_cast<std::int64_t>(batch_.size());
    // Every message received so far is in this batch (none is read while one is written):
    // their PUBACKs go now.
    sessions_.acknowledge();
    batch_.clear();
    rows_ = 0;
    bytes_ = 0;
    retrying_ = false;
    backoff_ = 100ms;
    retry_at_ = {};
    if (large_) {
      large_ = false;
      std::vector<Item>().swap(batch_);
      ::malloc_trim(0);
    }
  }

  void retry_later(const PgError& e) {
    if (!db_failing_) {
      spdlog::warn("ingest: {} (the batch's {} message(s) stay unacknowledged; retrying)", e.what(),
                   batch_.size());
    }
    db_failing_ = true;
    retrying_ = true;
    retry_at_ = Clock::now() + backoff_;
    backoff_ = std::min(backoff_ * 2, std::chrono::milliseconds(5000));
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
  IngestStore& store_;
  MqttSessions sessions_;
  int sigfd_;
  std::vector<Item> batch_;
  std::size_t rows_ = 0;
  std::size_t bytes_ = 0;
  bool large_ = false;
  Clock::time_point first_at_{};
  Clock::time_point retry_at_{};
  std::chrono::milliseconds backoff_{100};
  bool db_failing_ = false;
  bool retrying_ = false;
  bool stopping_ = false;
  long record_batches_ = 0;
  std::int64_t not_committed_ = 0;
  Counters counters_;
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
  IngestStore store(o.pg);
  try {
    const int applied = store.connect();
    if (applied > 0) spdlog::info("ingest: applied {} schema migration(s)", applied);
  } catch (const PgError& e) {
    std::cerr << "fleetgw ingest: " << e.what() << '\n';
    return 1;
  }
  if (o.gaps) return print_gaps(store);

  // Stop signals are read from a signalfd: no handler runs anywhere.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  ::sigprocmask(SIG_BLOCK, &signals, nullptr);
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
