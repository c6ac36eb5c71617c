// The ingest worker (ingest_worker.h): session processes, the batcher's poll loop, PostgreSQL.
#include "backend/ingest/ingest_worker.h"

#include <fmt/format.h>
#include <malloc.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/wait.h>
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
#include "backend/ingest/mqtt_session.h"
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

struct Session {
  pid_t pid = -1;
  int fd = -1;
  std::string in;  // bytes received, not yet a whole frame
  bool subscribed = false;
  bool resumed = false;
  bool disconnected = false;  // sent 'D': its connection to the broker is closed
  bool closed = false;        // EOF: the process is gone
};

// A received message waiting for its batch to commit.
struct Item {
  std::size_t session;
  std::string topic;
  std::size_t bytes;
  std::variant<Decoded, Reject> decoded;
};

std::uint32_t get_u32(std::string_view s) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(s[i]);
  return v;
}

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
  Worker(const IngestOptions& o, IngestStore& store, std::vector<Session> sessions, int sigfd)
      : o_(o), store_(store), sessions_(std::move(sessions)), sigfd_(sigfd) {
    if (const auto point = crash_point()) {
      const char* n = std::getenv("FLEETGW_INGEST_CRASH_BATCH");
      const long crash_batch = n != nullptr ? std::max(1L, std::atol(n)) : 1;
      store_.set_batch_hook([this, point, crash_batch](BatchPoint p) {
        if (p == *point && record_batches_ == crash_batch) ::kill(::getpid(), SIGKILL);
      });
    }
  }

  int run(const std::string& client_id, const std::string& filter) {
    const auto start = Clock::now();
    auto next_report = start + 60s;
    auto next_maintenance = start + 1h;
    bool announced = false;
    int status = 0;
    for (;;) {
      const auto now = Clock::now();
      poll_once(now);
      if (!announced && std::all_of(sessions_.begin(), sessions_.end(),
                                    [](const Session& s) { return s.subscribed; })) {
        announced = true;
        const auto resumed = std::count_if(sessions_.begin(), sessions_.end(),
                                           [](const Session& s) { return s.resumed; });
        const auto k = static_cast<long>(sessions_.size());
        spdlog::info("ingest: connected to {} as {}-s1..s{} ({} sessions, {}), subscribed to {}",
                     o_.broker, client_id, k, k,
                     resumed == k   ? "session resumed"
                     : resumed == 0 ? "session new"
                                    : fmt::format("{} of {} sessions resumed", resumed, k),
                     filter);
      }
      if (should_flush(Clock::now())) flush();
      if (!stopping_) {
        if (std::any_of(sessions_.begin(), sessions_.end(),
                        [](const Session& s) { return s.closed; })) {
          spdlog::error("ingest: a session process ended unexpectedly; stopping");
          status = 1;
          begin_stop();
        } else if (o_.duration_s > 0 &&
                   Clock::now() - start >= std::chrono::duration<double>(o_.duration_s)) {
          begin_stop();
        }
      }
      if (Clock::now() >= next_report) {
        spdlog::info("{}", summary(counters_));
        next_report += 60s;
      }
      if (Clock::now() >= next_maintenance) {
        next_maintenance += 1h;
        maintain();
      }
      if (stopping_ && std::all_of(sessions_.begin(), sessions_.end(),
                                   [](const Session& s) { return s.closed; })) {
        break;
      }
    }
    for (Session& s : sessions_) ::waitpid(s.pid, nullptr, 0);
    if (!batch_.empty()) not_committed_ += static_cast<std::int64_t>(batch_.size());
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
  void begin_stop() {
    if (stopping_) return;
    stopping_ = true;
    for (Session& s : sessions_) {
      if (!s.closed) ::kill(s.pid, SIGTERM);
    }
  }

  void poll_once(Clock::time_point now) {
    std::vector<pollfd> fds;
    fds.push_back({sigfd_, POLLIN, 0});
    for (const Session& s : sessions_) fds.push_back({s.closed ? -1 : s.fd, POLLIN, 0});
    auto wake = now + 1s;
    if (!batch_.empty()) wake = std::min(wake, std::max(retry_at_, first_at_ + delay()));
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(wake - now).count();
    ::poll(fds.data(), fds.size(), static_cast<int>(std::max<long long>(0, ms)));
    if (fds[0].revents & POLLIN) {
      signalfd_siginfo info{};
      while (::read(sigfd_, &info, sizeof info) == sizeof info) {
        if (info.ssi_signo == SIGINT || info.ssi_signo == SIGTERM) begin_stop();
      }
    }
    for (std::size_t i = 0; i < sessions_.size(); ++i) {
      if (fds[i + 1].revents & (POLLIN | POLLHUP | POLLERR)) read_session(i);
    }
  }

  std::chrono::milliseconds delay() const { return std::chrono::milliseconds(o_.batch_delay_ms); }

  void read_session(std::size_t i) {
    Session& s = sessions_[i];
    char buf[64 * 1024];
    const ssize_t n = ::read(s.fd, buf, sizeof buf);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) return;
    if (n <= 0) {
      s.closed = true;
      ::close(s.fd);
      // Its message, if any, can no longer be acknowledged: the broker keeps it.
      std::erase_if(batch_, [&](const Item& it) { return it.session == i; });
      return;
    }
    s.in.append(buf, static_cast<std::size_t>(n));
    for (;;) {
      if (s.in.empty()) break;
      const char type = s.in[0];
      if (type == 'S') {
        if (s.in.size() < 2) break;
        s.subscribed = true;
        s.resumed = s.in[1] != 0;
        s.in.erase(0, 2);
      } else if (type == 'D') {
        s.disconnected = true;
        s.in.erase(0, 1);
      } else if (type == 'M') {
        if (s.in.size() < 9) break;
        const std::size_t tl = get_u32(std::string_view(s.in).substr(1, 4));
        const std::size_t pl = get_u32(std::string_view(s.in).substr(5, 4));
        if (s.in.size() < 9 + tl + pl) break;
        const std::string_view topic = std::string_view(s.in).substr(9, tl);
        const std::string_view payload = std::string_view(s.in).substr(9 + tl, pl);
        add(i, topic, payload);
        s.in.erase(0, 9 + tl + pl);
        if (pl > kLargeMessageBytes) std::string().swap(s.in);
      } else {
        spdlog::error("ingest: session {} sent an unknown frame; dropping it", i + 1);
        s.closed = true;
        ::close(s.fd);
        break;
      }
    }
  }

  void add(std::size_t session, std::string_view topic, std::string_view payload) {
    if (batch_.empty()) first_at_ = Clock::now();
    Item item{session, std::string(topic), payload.size(),
              decode_message(o_.topic_prefix, topic, payload)};
    if (const auto* d = std::get_if<Decoded>(&item.decoded)) {
      for (const RowSet& r : d->rows) rows_ += r.rows();
    }
    large_ = large_ || payload.size() > kLargeMessageBytes;
    batch_.push_back(std::move(item));
  }

  bool should_flush(Clock::time_point now) const {
    if (batch_.empty() || now < retry_at_) return false;
    const auto live = std::count_if(sessions_.begin(), sessions_.end(),
                                    [](const Session& s) { return !s.closed && !s.disconnected; });
    return stopping_ || rows_ >= o_.batch_rows || static_cast<long>(batch_.size()) >= live ||
           now >= first_at_ + delay();
  }

  void reply(std::size_t session, char answer) {
    Session& s = sessions_[session];
    if (s.closed) return;
    if (::send(s.fd, &answer, 1, MSG_NOSIGNAL) != 1) s.closed = true;
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
      const BatchResult r = store_.write_batch(messages, rejects);
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
    for (const Item& it : batch_) reply(it.session, 'A');  // the PUBACKs go now
    batch_.clear();
    rows_ = 0;
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
    if (!stopping_) return;
    // Stopping: a session already disconnected from the broker is let go; its message was not
    // acknowledged (the connection is closed) and comes again.
    std::erase_if(batch_, [&](const Item& it) {
      if (!sessions_[it.session].disconnected) return false;
      reply(it.session, 'N');
      ++not_committed_;
      return true;
    });
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
  std::vector<Session> sessions_;
  int sigfd_;
  std::vector<Item> batch_;
  std::size_t rows_ = 0;
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

  // Stop signals and SIGCHLD are read from a signalfd (this process) or sigwait (the sessions,
  // which inherit the mask): no handler runs anywhere.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGCHLD);
  ::sigprocmask(SIG_BLOCK, &signals, nullptr);

  const std::string client_id = o.client_id.empty() ? default_client_id(o.group) : o.client_id;
  std::vector<Session> sessions;
  for (std::size_t i = 1; i <= std::max<std::size_t>(1, o.sessions); ++i) {
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
      std::cerr << "fleetgw ingest: socketpair failed\n";
      return 1;
    }
    const pid_t pid = ::fork();
    if (pid == 0) {
      // The session process keeps stdio and its socket (as fd 3) only: not the database
      // connection or the other sessions' sockets. _exit: a forked copy must not run the
      // parent's exit handlers or destructors.
      ::dup2(sv[1], 3);
      ::close_range(4, ~0U, 0);
      ::_exit(run_session(o, client_id + "-s" + std::to_string(i), i == 1, 3));
    }
    ::close(sv[1]);
    if (pid < 0) {
      ::close(sv[0]);
      std::cerr << "fleetgw ingest: fork failed\n";
      break;
    }
    Session s;
    s.pid = pid;
    s.fd = sv[0];
    sessions.push_back(std::move(s));
  }
  const int sigfd = ::signalfd(-1, &signals, SFD_NONBLOCK | SFD_CLOEXEC);
  const std::string filter = "$share/" + o.group + "/" + o.topic_prefix + "/#";
  Worker worker(o, store, std::move(sessions), sigfd);
  worker.maintain();
  const int status = worker.run(client_id, filter);
  ::close(sigfd);
  return status;
}

}  // namespace fleetgw::ingest
