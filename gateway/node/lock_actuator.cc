#include "gateway/node/lock_actuator.h"

#include <algorithm>
#include <utility>

#include "gateway/node/messages.h"

namespace fleetgw::node {
namespace {

uint8_t target_state(LockTarget t) {
  return t == LockTarget::kLocked ? lock_state::kLocked : lock_state::kUnlocked;
}
uint8_t failure_state(LockTarget t) {
  return t == LockTarget::kLocked ? lock_state::kLockFailed : lock_state::kUnlockFailed;
}
uint8_t progress_state(LockTarget t) {
  return t == LockTarget::kLocked ? lock_state::kLocking : lock_state::kUnlocking;
}

}  // namespace

std::string_view lock_target_name(LockTarget t) {
  return t == LockTarget::kLocked ? "locked" : "unlocked";
}

std::string_view lock_outcome_name(LockOutcome o) {
  switch (o) {
    case LockOutcome::kSucceeded:
      return "succeeded";
    case LockOutcome::kFailed:
      return "failed";
    case LockOutcome::kTimeout:
      return "timeout";
  }
  return "?";
}

std::string_view lock_start_name(LockStart s) {
  switch (s) {
    case LockStart::kStarted:
      return "started";
    case LockStart::kBusy:
      return "busy";
    case LockStart::kNotFitted:
      return "not_fitted";
    case LockStart::kBadIndex:
      return "bad_index";
  }
  return "?";
}

LockActuator::LockActuator(std::array<bool, motinova::kLockCount> fitted, LockPolicy policy,
                           RequestPolicy requests, int command_transmissions, RequestEngine& engine)
    : fitted_(fitted),
      policy_(policy),
      requests_(requests),
      command_transmissions_(std::max(1, command_transmissions)),
      engine_(engine) {}

LockActuator::~LockActuator() {
  for (auto& job : jobs_) {
    if (job && job->read_id != 0) engine_.cancel(job->read_id, last_now_);
  }
}

LockStart LockActuator::start(int k, LockTarget target, Micros now, Callback on_done,
                              std::optional<Micros> timeout) {
  if (k < 0 || k >= motinova::kLockCount) return LockStart::kBadIndex;
  const auto i = static_cast<std::size_t>(k);
  if (!fitted_[i]) return LockStart::kNotFitted;
  if (jobs_[i]) return LockStart::kBusy;
  last_now_ = now;
  Job& job = jobs_[i].emplace(Job{});  // Job{}: clang cannot default-construct a nested class here
  job.target = target;
  job.started = now;
  job.deadline = now + timeout.value_or(policy_.timeout);
  job.on_done = std::move(on_done);
  job.initial_state = last_state_[i];
  send_command(k, job, now);
  // The first status read follows one interval later: a read queued right behind the command
  // would mostly report the state from before the command.
  job.last_read = now;
  return LockStart::kStarted;
}

void LockActuator::on_frame(const motinova::AppFrame& frame, Micros now) {
  last_now_ = now;
  for (int k = 0; k < motinova::kLockCount; ++k) {
    if (const auto state = lock_state_of(frame, k)) {
      last_state_[static_cast<std::size_t>(k)] = *state;
      observe(k, *state, now);
      return;
    }
  }
}

void LockActuator::tick(Micros now) {
  last_now_ = now;
  for (int k = 0; k < motinova::kLockCount; ++k) {
    auto& slot = jobs_[static_cast<std::size_t>(k)];
    if (!slot) continue;
    Job& job = *slot;
    if (now >= job.deadline) {
      finish(k, LockOutcome::kTimeout, now);
      continue;
    }
    if (!job.reacted && job.commands_sent < command_transmissions_ &&
        now - job.last_command >= policy_.command_repeat_interval) {
      send_command(k, job, now);
    }
    if (job.read_id == 0 && now - job.last_read >= policy_.status_interval) {
      send_read(k, job, now);
    }
  }
}

Micros LockActuator::next_event() const {
  Micros next = Micros::max();
  for (const auto& slot : jobs_) {
    if (!slot) continue;
    const Job& job = *slot;
    next = std::min(next, job.deadline);
    if (!job.reacted && job.commands_sent < command_transmissions_) {
      next = std::min(next, job.last_command + policy_.command_repeat_interval);
    }
    if (job.read_id == 0) next = std::min(next, job.last_read + policy_.status_interval);
  }
  return next;
}

bool LockActuator::any_busy() const {
  return std::any_of(jobs_.begin(), jobs_.end(), [](const auto& j) { return j.has_value(); });
}

bool LockActuator::busy(int k) const {
  return k >= 0 && k < motinova::kLockCount && jobs_[static_cast<std::size_t>(k)].has_value();
}

std::optional<uint8_t> LockActuator::last_state(int k) const {
  if (k < 0 || k >= motinova::kLockCount) return std::nullopt;
  return last_state_[static_cast<std::size_t>(k)];
}

void LockActuator::send_command(int k, Job& job, Micros now) {
  const uint8_t f = ids::lock_function_base(k);
  const bool lock = job.target == LockTarget::kLocked;
  Request req;
  req.frame = keyword_frame(ids::lock_command_id(k), motinova::Mode::kWrite,
                            static_cast<uint8_t>(f + (lock ? 2 : 3)),
                            lock ? keyword::kLock : keyword::kUnlock);
  // No answers: a write is sent once when the lock's ID is free; confirmation is the status.
  ++job.commands_sent;
  job.last_command = now;
  engine_.submit(std::move(req), nullptr, now);
}

void LockActuator::send_read(int k, Job& job, Micros now) {
  const uint8_t f = ids::lock_function_base(k);
  Request req;
  req.frame = read_request(ids::lock_command_id(k), static_cast<uint8_t>(f + 1));
  req.answers = {{ids::lock_broadcast_id(k), fn::kLockStatus}};
  // A read never outlives the job: it expires with the job's deadline at the latest, so nothing
  // goes out for a job that is over.
  req.timing = {policy_.status_interval, std::min(requests_.timeout, job.deadline - now)};
  job.last_read = now;
  job.read_id = engine_.submit(
      std::move(req),
      [this, k](const RequestResult&) {
        // The answer itself is handled by on_frame(); here the next read is just allowed.
        if (auto& j = jobs_[static_cast<std::size_t>(k)]) j->read_id = 0;
      },
      now);
}

void LockActuator::observe(int k, uint8_t state, Micros now) {
  auto& slot = jobs_[static_cast<std::size_t>(k)];
  if (!slot) return;
  Job& job = *slot;
  job.state = state;
  if (state != job.initial_state) job.changed = true;
  if (state == target_state(job.target)) {
    job.reacted = true;
    finish(k, LockOutcome::kSucceeded, now);
    return;
  }
  if (state == failure_state(job.target)) {
    // A failure that was already showing before start() is from an earlier attempt until the
    // lock reports something else in between.
    if (job.initial_state != state || job.changed) {
      job.reacted = true;
      finish(k, LockOutcome::kFailed, now);
    }
    return;
  }
  if (state == progress_state(job.target)) job.reacted = true;
}

void LockActuator::finish(int k, LockOutcome outcome, Micros now) {
  auto& slot = jobs_[static_cast<std::size_t>(k)];
  Job job = std::move(*slot);
  slot.reset();  // before the callback, which may start the next job on this lock
  if (job.read_id != 0) engine_.cancel(job.read_id, now);
  LockResult r;
  r.lock_index = k;
  r.target = job.target;
  r.outcome = outcome;
  r.final_state = job.state;
  r.elapsed = now - job.started;
  r.commands_sent = job.commands_sent;
  if (job.on_done) job.on_done(r);
}

}  // namespace fleetgw::node
