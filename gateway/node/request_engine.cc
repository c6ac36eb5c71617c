#include "gateway/node/request_engine.h"

#include <algorithm>
#include <utility>

namespace fleetgw::node {

std::string_view request_outcome_name(RequestOutcome o) {
  switch (o) {
    case RequestOutcome::kAnswered:
      return "answered";
    case RequestOutcome::kTimedOut:
      return "timed_out";
    case RequestOutcome::kSent:
      return "sent";
    case RequestOutcome::kSendFailed:
      return "send_failed";
  }
  return "?";
}

RequestId RequestEngine::submit(Request request, Callback on_done, Micros now) {
  const uint16_t target = request.frame.can_id;
  Channel& ch = channels_[target];
  Pending p;
  p.id = next_id_++;
  p.request = std::move(request);
  p.on_done = std::move(on_done);
  const RequestId id = p.id;
  ch.queue.push_back(std::move(p));
  std::vector<Completion> done;
  if (!ch.active) advance(ch, now, done);
  fire(done);
  return id;
}

bool RequestEngine::cancel(RequestId id, Micros now) {
  for (auto& [target, ch] : channels_) {
    if (ch.active && ch.active->id == id) {
      ch.active.reset();
      std::vector<Completion> done;
      advance(ch, now, done);
      fire(done);
      return true;
    }
    const auto it = std::find_if(ch.queue.begin(), ch.queue.end(),
                                 [&](const Pending& p) { return p.id == id; });
    if (it != ch.queue.end()) {
      ch.queue.erase(it);
      return true;
    }
  }
  return false;
}

void RequestEngine::on_frame(const motinova::AppFrame& frame, Micros now) {
  std::vector<Completion> done;
  for (auto& [target, ch] : channels_) {
    if (!ch.active) continue;
    const auto& answers = ch.active->request.answers;
    const auto hit = std::find_if(answers.begin(), answers.end(),
                                  [&](const MessageKey& k) { return k.matches(frame); });
    if (hit == answers.end()) continue;
    const MessageKey key = *hit;
    ++stats_.answered;
    complete(*ch.active, RequestOutcome::kAnswered, now, key, done);
    ch.active.reset();
    advance(ch, now, done);
  }
  fire(done);
}

void RequestEngine::tick(Micros now) {
  std::vector<Completion> done;
  for (auto& [target, ch] : channels_) {
    if (!ch.active) continue;
    Pending& p = *ch.active;
    // Timeout is checked first: a request never goes out again at the moment it expires.
    if (now - p.first_sent >= p.request.timing.timeout) {
      ++stats_.timed_out;
      complete(p, RequestOutcome::kTimedOut, now, std::nullopt, done);
      ch.active.reset();
      advance(ch, now, done);
    } else if (now - p.last_sent >= p.request.timing.retry_interval) {
      transmit(p, now);
    }
  }
  fire(done);
}

Micros RequestEngine::next_event() const {
  Micros next = Micros::max();
  for (const auto& [target, ch] : channels_) {
    if (!ch.active) continue;
    const Pending& p = *ch.active;
    next = std::min({next, p.first_sent + p.request.timing.timeout,
                     p.last_sent + p.request.timing.retry_interval});
  }
  return next;
}

bool RequestEngine::busy(uint16_t target_id) const {
  const auto it = channels_.find(target_id);
  return it != channels_.end() && it->second.active.has_value();
}

bool RequestEngine::queued(RequestId id) const {
  for (const auto& [target, ch] : channels_) {
    for (const Pending& p : ch.queue) {
      if (p.id == id) return true;
    }
  }
  return false;
}

std::size_t RequestEngine::pending(uint16_t target_id) const {
  const auto it = channels_.find(target_id);
  if (it == channels_.end()) return 0;
  return it->second.queue.size() + (it->second.active ? 1 : 0);
}

std::size_t RequestEngine::pending() const {
  std::size_t n = 0;
  for (const auto& [target, ch] : channels_) n += ch.queue.size() + (ch.active ? 1 : 0);
  return n;
}

void RequestEngine::transmit(Pending& p, Micros now) {
  if (p.transmissions == 0) p.first_sent = now;
  p.last_sent = now;
  ++p.transmissions;
  ++stats_.transmissions;
  if (!sender_.send(p.request.frame)) ++stats_.send_failures;
}

void RequestEngine::advance(Channel& ch, Micros now, std::vector<Completion>& done) {
  while (!ch.active && !ch.queue.empty()) {
    Pending p = std::move(ch.queue.front());
    ch.queue.pop_front();
    if (p.request.answers.empty()) {
      // A write: one transmission, nothing to wait for; the next request may follow at once
      // (the sender queues whole messages, so they cannot interleave on the wire).
      p.first_sent = now;
      p.last_sent = now;
      p.transmissions = 1;
      ++stats_.transmissions;
      const bool ok = sender_.send(p.request.frame);
      if (!ok) ++stats_.send_failures;
      complete(p, ok ? RequestOutcome::kSent : RequestOutcome::kSendFailed, now, std::nullopt,
               done);
      continue;
    }
    ch.active = std::move(p);
    transmit(*ch.active, now);
  }
}

void RequestEngine::complete(Pending& p, RequestOutcome outcome, Micros now,
                             std::optional<MessageKey> by, std::vector<Completion>& done) {
  RequestResult r;
  r.id = p.id;
  r.outcome = outcome;
  r.target_id = p.request.frame.can_id;
  r.transmissions = p.transmissions;
  r.latency = now - p.first_sent;
  r.completed = now;
  r.answered_by = by;
  if (p.on_done) done.emplace_back(std::move(p.on_done), r);
}

void RequestEngine::fire(std::vector<Completion>& done) {
  for (auto& [callback, result] : done) callback(result);
}

}  // namespace fleetgw::node
