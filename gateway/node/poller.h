// Keeps the blocks of the poll table fresh by reading them through the RequestEngine: model info
// at start-up, periodic reads of what is not broadcast, and a read of any broadcast block that
// has gone stale (spec §3.7, U12, U16).
//
// Contract:
//  * An entry's answer is fresh when any of its answer keys was received within `period`,
//    whether as the answer to our read or as a spontaneous broadcast; fresh entries are not read.
//  * Once-entries (period 0) are due at start(); periodic ones at start() + min(period,
//    startup_grace), giving broadcasts a chance first. A periodic entry is due again `period`
//    after its newest answer. An entry is never submitted twice at once.
//  * After a timeout the entry waits failure_backoff, doubled per consecutive failure up to
//    max_failure_backoff; an answer resets the back-off.
//  * rearm(node) makes the once-entries of that node due again (the node came back online,
//    possibly as a different unit after a battery swap) and cuts the back-off of its periodic
//    entries short (due within min(period, startup_grace)).
//  * Parked mode (set_parked): while set, every periodic entry whose own period is at least
//    kSlowEntryPeriod (pack statistics, odometer, MC settings: blocks that are read, not
//    broadcast) waits at least `slow_min`, and every faster one (the stale-rule reads of
//    broadcast blocks) at least `fast_min`, which the configuration keeps below the node's
//    offline and fault-stale timeouts so that a node that must be polled is never taken for a
//    silent one. Clearing it restores the table's periods at once: an entry overdue by its own
//    period is due immediately. Answers are recorded the same way in both modes.
//  * Every completed read is reported through the result callback (answered / timed out,
//    latency, transmissions). Reads go through the RequestEngine, which enforces one outstanding
//    request per target ID.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gateway/node/node_config.h"
#include "gateway/node/request_engine.h"

namespace fleetgw::node {

struct ParkedPolling {
  Micros slow_min{0};  // entries of >= Poller::kSlowEntryPeriod
  Micros fast_min{0};  // the others
};

struct PollResult {
  const PollEntry* entry = nullptr;  // valid as long as the Poller lives
  RequestResult request;
};

struct PollEntryStatus {
  bool in_flight = false;
  bool done = false;                  // once-entry answered
  std::optional<Micros> last_answer;  // newest answer (or broadcast of the block)
  Micros next_due{0};
  int consecutive_failures = 0;
  uint64_t answered = 0;
  uint64_t timed_out = 0;
};

class Poller {
 public:
  using ResultCallback = std::function<void(const PollResult&)>;

  Poller(std::vector<PollEntry> table, RequestPolicy policy, RequestEngine& engine);
  ~Poller();
  Poller(const Poller&) = delete;
  Poller& operator=(const Poller&) = delete;

  void set_result_callback(ResultCallback cb) { on_result_ = std::move(cb); }

  void start(Micros now);
  void on_frame(const motinova::AppFrame& frame, Micros now);
  void tick(Micros now);
  // The earliest time an entry is due (Micros::max(): none, or not started).
  Micros next_event() const;
  void rearm(motinova::Node node, Micros now);
  // See the contract; nullopt = the table's own periods.
  void set_parked(std::optional<ParkedPolling> parked, Micros now);
  static constexpr Micros kSlowEntryPeriod{5'000'000};
  // The period entry `index` is read with now (the table's, or the parked minimum).
  Micros period(std::size_t index) const;

  std::span<const PollEntry> table() const { return table_; }
  const PollEntryStatus& status(std::size_t index) const { return status_[index]; }

 private:
  void submit(std::size_t index, Micros now);
  void on_done(std::size_t index, const RequestResult& r);
  void record_answer(std::size_t index, Micros now);
  Micros backoff(int failures) const;

  std::vector<PollEntry> table_;
  std::vector<PollEntryStatus> status_;
  std::vector<RequestId> in_flight_ids_;
  RequestPolicy policy_;
  RequestEngine& engine_;
  ResultCallback on_result_;
  bool started_ = false;
  std::optional<ParkedPolling> parked_;
  Micros last_now_{0};  // latest time seen, for cancelling requests in the destructor
};

}  // namespace fleetgw::node
