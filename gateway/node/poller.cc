#include "gateway/node/poller.h"

#include <algorithm>
#include <utility>

namespace fleetgw::node {

Poller::Poller(std::vector<PollEntry> table, RequestPolicy policy, RequestEngine& engine)
    : table_(std::move(table)),
      status_(table_.size()),
      in_flight_ids_(table_.size(), 0),
      policy_(policy),
      engine_(engine) {}

Poller::~Poller() {
  // The engine may outlive us and its callbacks capture `this`: withdraw our requests. Queued
  // ones go first, so cancelling an outstanding one cannot put another of ours on the bus.
  for (RequestId id : in_flight_ids_) {
    if (id != 0 && engine_.queued(id)) engine_.cancel(id, last_now_);
  }
  for (RequestId id : in_flight_ids_) {
    if (id != 0) engine_.cancel(id, last_now_);
  }
}

void Poller::start(Micros now) {
  started_ = true;
  last_now_ = now;
  for (std::size_t i = 0; i < table_.size(); ++i) {
    PollEntryStatus& s = status_[i];
    if (s.last_answer && table_[i].period > Micros{0}) continue;  // seen before start()
    if (s.done) continue;
    s.next_due = table_[i].period == Micros{0}
                     ? now
                     : now + std::min(table_[i].period, policy_.startup_grace);
  }
  tick(now);
}

void Poller::on_frame(const motinova::AppFrame& frame, Micros now) {
  last_now_ = now;
  for (std::size_t i = 0; i < table_.size(); ++i) {
    const auto& answers = table_[i].answers;
    if (std::any_of(answers.begin(), answers.end(),
                    [&](const MessageKey& k) { return k.matches(frame); })) {
      record_answer(i, now);
    }
  }
}

void Poller::record_answer(std::size_t index, Micros now) {
  PollEntryStatus& s = status_[index];
  s.last_answer = now;
  s.consecutive_failures = 0;
  if (table_[index].period == Micros{0}) {
    s.done = true;
  } else {
    s.next_due = now + period(index);
  }
}

Micros Poller::period(std::size_t index) const {
  const Micros own = table_[index].period;
  if (!parked_ || own == Micros{0}) return own;
  return std::max(own, own >= kSlowEntryPeriod ? parked_->slow_min : parked_->fast_min);
}

void Poller::set_parked(std::optional<ParkedPolling> parked, Micros now) {
  last_now_ = now;
  if (parked_.has_value() == parked.has_value() &&
      (!parked ||
       (parked_->slow_min == parked->slow_min && parked_->fast_min == parked->fast_min))) {
    return;
  }
  parked_ = parked;
  for (std::size_t i = 0; i < table_.size(); ++i) {
    PollEntryStatus& s = status_[i];
    // Entries in flight, backing off or never answered keep their schedule.
    if (table_[i].period == Micros{0} || s.in_flight || s.consecutive_failures > 0 ||
        !s.last_answer) {
      continue;
    }
    s.next_due = *s.last_answer + period(i);
  }
}

void Poller::tick(Micros now) {
  last_now_ = now;
  if (!started_) return;
  for (std::size_t i = 0; i < table_.size(); ++i) {
    const PollEntryStatus& s = status_[i];
    if (s.in_flight || s.done || now < s.next_due) continue;
    submit(i, now);
  }
}

Micros Poller::next_event() const {
  Micros next = Micros::max();
  if (!started_) return next;
  for (const PollEntryStatus& s : status_) {
    if (!s.in_flight && !s.done) next = std::min(next, s.next_due);
  }
  return next;
}

void Poller::rearm(motinova::Node node, Micros now) {
  last_now_ = now;
  for (std::size_t i = 0; i < table_.size(); ++i) {
    if (motinova::target_of(table_[i].target_id) != node) continue;
    PollEntryStatus& s = status_[i];
    if (table_[i].period == Micros{0}) {
      s.done = false;
      s.next_due = now;
    } else if (s.consecutive_failures > 0) {
      // Cut the back-off short but still give the returning node's broadcasts a moment.
      s.next_due = std::min(s.next_due, now + std::min(table_[i].period, policy_.startup_grace));
    }
    s.consecutive_failures = 0;
  }
}

void Poller::submit(std::size_t index, Micros now) {
  const PollEntry& e = table_[index];
  status_[index].in_flight = true;
  Request req;
  req.frame = read_request(e.target_id, static_cast<uint8_t>(e.command >> 8));
  req.answers = e.answers;
  req.timing = {policy_.retry_interval, policy_.timeout};
  // The engine may complete a request synchronously only for writes; reads always wait, so the
  // id is stored before the callback can run.
  in_flight_ids_[index] = engine_.submit(
      std::move(req), [this, index](const RequestResult& r) { on_done(index, r); }, now);
}

void Poller::on_done(std::size_t index, const RequestResult& r) {
  PollEntryStatus& s = status_[index];
  s.in_flight = false;
  in_flight_ids_[index] = 0;
  if (r.outcome == RequestOutcome::kAnswered) {
    ++s.answered;
    // Usually on_frame() saw the same frame already; recording twice is harmless.
    record_answer(index, r.completed);
  } else {
    ++s.timed_out;
    ++s.consecutive_failures;
    s.next_due = r.completed + backoff(s.consecutive_failures);
  }
  if (on_result_) on_result_(PollResult{&table_[index], r});
}

Micros Poller::backoff(int failures) const {
  Micros b = policy_.failure_backoff;
  for (int i = 1; i < failures && b < policy_.max_failure_backoff; ++i) b *= 2;
  return std::min(b, policy_.max_failure_backoff);
}

}  // namespace fleetgw::node
