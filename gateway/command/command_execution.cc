// Execution: the journal entry first, then the locks one at a time on the bus, then the
// combined result.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/command/command_service_impl.h"
#include "gateway/domain/domain_trackers.h"
#include "motinova/catalogue.h"

namespace fleetgw::command {
namespace {

using node::LockOutcome;
using node::LockTarget;

v1::CommandResultCode code_of(LockOutcome o) {
  switch (o) {
    case LockOutcome::kSucceeded:
      return v1::COMMAND_RESULT_CODE_SUCCEEDED;
    case LockOutcome::kFailed:
      return v1::COMMAND_RESULT_CODE_FAILED;
    case LockOutcome::kTimeout:
      return v1::COMMAND_RESULT_CODE_TIMEOUT;
  }
  return v1::COMMAND_RESULT_CODE_UNSPECIFIED;
}

// Severity for combining the locks of a whole-vehicle command: the worst one wins.
int severity(v1::CommandResultCode c) {
  switch (c) {
    case v1::COMMAND_RESULT_CODE_SUCCEEDED:
      return 0;
    case v1::COMMAND_RESULT_CODE_TIMEOUT:
      return 1;
    case v1::COMMAND_RESULT_CODE_FAILED:
      return 2;
    default:
      return 3;
  }
}

}  // namespace

std::optional<Disposition> CommandService::Impl::journal_executing(const VerifiedCommand& cmd,
                                                                   Micros now) {
  storage::Batch b;
  b.now_us = now.count();
  b.commands.push_back({cmd.command_id, now.count(), std::string(kExecuting),
                        cmd.expires_at.count(), cmd.command_sha256});
  remember(cmd, std::max(cmd.expires_at, wall(now) + config.rejected_retention));
  if (const auto error = write_batch(context.store, b)) {
    ++stats.storage_errors;
    spdlog::error("command {}: journal write failed: {}", cmd.command_id, *error);
    // Journaled as rejected once the store accepts writes again (see store_result).
    Rejection rej{RejectReason::kStorageError, "journal write failed: " + *error, cmd.command_id,
                  true, cmd.command_sha256};
    rej.operator_id = cmd.operator_id;
    return reject(rej, now, cmd.expires_at, /*always_answer=*/true);
  }
  ++stats.accepted;
  return std::nullopt;
}

Disposition CommandService::Impl::start(VerifiedCommand cmd, Micros now) {
  // The journal entry is on disk before anything is written to the bus.
  if (const auto rejected = journal_executing(cmd, now)) return *rejected;
  auto run = std::make_unique<Running>();
  run->received = now;
  for (const int k : lock_indices(cmd)) {
    Step s;
    s.lock_index = k;
    s.result.set_lock_kind(std::string(kind_of(k)));
    run->steps.push_back(std::move(s));
  }
  run->cmd = std::move(cmd);
  // The lock kind and key id were matched against the configuration: safe to log as they are.
  spdlog::info("command {}: {} {} accepted (key {})", run->cmd.command_id,
               run->cmd.target == LockTarget::kLocked ? "lock" : "unlock",
               run->cmd.whole_vehicle ? "vehicle" : run->cmd.lock_kind, run->cmd.key_id);
  Running* r = run.get();
  running.push_back(std::move(run));
  // Rental start: the vehicle UNLOCK broadcast goes before the locks open.
  if (r->cmd.whole_vehicle && r->cmd.target == LockTarget::kUnlocked) {
    if (context.trackers != nullptr) {
      context.trackers->expect_lock_command(motinova::Node::kBroadcast, r->cmd.command_id, now);
    }
    context.node.vehicle_unlock(now);
    r->broadcast_sent = true;
  }
  advance(*r, now);
  return Disposition::kStarted;
}

// Runs the next step of `r`, or finishes it. May destroy `r`.
void CommandService::Impl::advance(Running& r, Micros now) {
  while (r.next < r.steps.size()) {
    Step& s = r.steps[r.next];
    if (s.attempts == 0) {
      s.started = now;
      // Conditions may have changed since acceptance (a whole-vehicle sequence takes seconds).
      if (auto rej = interlock(s.lock_index, r.cmd.target, now)) {
        s.result.set_result(v1::COMMAND_RESULT_CODE_FAILED);
        s.result.set_reason(std::string(reject_reason_name(rej->reason)) + ": " + rej->detail);
        ++r.next;
        continue;
      }
    }
    if (attempt(r, s, now)) return;  // a callback continues the sequence
    ++r.next;
  }
  if (r.cmd.whole_vehicle && r.cmd.target == LockTarget::kLocked && !r.broadcast_sent) {
    // Rental end: the vehicle LOCK broadcast after every lock was driven.
    if (context.trackers != nullptr) {
      context.trackers->expect_lock_command(motinova::Node::kBroadcast, r.cmd.command_id, now);
    }
    context.node.vehicle_lock(now);
    r.broadcast_sent = true;
  }
  finish(r, now);
}

// Starts one actuation attempt; false when it could not start (step already finished).
bool CommandService::Impl::attempt(Running& r, Step& s, Micros now) {
  ++s.attempts;
  s.attempt_started = now;
  if (context.trackers != nullptr) {
    context.trackers->expect_lock_command(motinova::lock_node(s.lock_index), r.cmd.command_id, now);
  }
  std::weak_ptr<Impl> weak = weak_from_this();
  const std::string id = r.cmd.command_id;
  const node::LockStart started = context.node.actuate_lock(
      s.lock_index, r.cmd.target, now,
      [weak, id](const node::LockResult& res) {
        if (auto self = weak.lock()) self->on_lock_result(id, res);
      },
      config.confirm_timeout);
  if (started == node::LockStart::kStarted) return true;
  s.result.set_result(v1::COMMAND_RESULT_CODE_FAILED);
  s.result.set_reason("actuation_refused: " + std::string(node::lock_start_name(started)));
  return false;
}

void CommandService::Impl::on_lock_result(const std::string& id, const node::LockResult& res) {
  Running* r = find_running(id);
  if (r == nullptr || r->next >= r->steps.size()) return;
  Step& s = r->steps[r->next];
  if (s.lock_index != res.lock_index) return;
  const Micros now = s.attempt_started + res.elapsed;
  s.commands_sent += res.commands_sent;
  s.result.set_final_lock_state(proto_state(res.final_state));
  s.result.set_final_lock_state_name(state_name(res.final_state));
  if (res.outcome == LockOutcome::kTimeout && s.attempts <= config.retries) {
    spdlog::warn("command {}: {} lock did not confirm within {} ms; retrying ({}/{})", id,
                 kind_of(s.lock_index), to_ms(config.confirm_timeout), s.attempts, config.retries);
    if (attempt(*r, s, now)) return;
  } else {
    s.result.set_result(code_of(res.outcome));
    if (res.outcome == LockOutcome::kFailed) {
      s.result.set_reason("lock_failed: the lock reported " +
                          (res.final_state ? state_name(res.final_state) : "a failure"));
    } else if (res.outcome == LockOutcome::kTimeout) {
      s.result.set_reason("no_confirmation: no target or failure state within " +
                          std::to_string(to_ms(config.confirm_timeout)) + " ms, " +
                          std::to_string(s.attempts) + " attempt(s)");
    }
  }
  s.result.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - s.started)));
  s.result.set_commands_sent(static_cast<std::uint32_t>(s.commands_sent));
  ++r->next;
  advance(*r, now);
}

void CommandService::Impl::finish(Running& r, Micros now) {
  v1::CommandResult out;
  out.set_command_id(r.cmd.command_id);
  out.set_command_sha256(r.cmd.command_sha256);
  out.set_operator_id(r.cmd.operator_id);
  v1::CommandResultCode worst = v1::COMMAND_RESULT_CODE_SUCCEEDED;
  const v1::LockActionResult* worst_step = nullptr;
  for (const Step& s : r.steps) {
    *out.add_locks() = s.result;
    if (severity(s.result.result()) > severity(worst)) {
      worst = s.result.result();
      worst_step = &s.result;
    }
  }
  out.set_result(worst);
  const bool target_locked = r.cmd.target == LockTarget::kLocked;
  if (worst_step != nullptr) {
    out.set_reason(r.cmd.whole_vehicle ? worst_step->lock_kind() + " " + worst_step->reason()
                                       : worst_step->reason());
    out.set_final_lock_state(worst_step->final_lock_state());
    out.set_final_lock_state_name(worst_step->final_lock_state_name());
  } else if (r.steps.size() == 1) {
    out.set_final_lock_state(r.steps[0].result.final_lock_state());
    out.set_final_lock_state_name(r.steps[0].result.final_lock_state_name());
  } else {
    // Whole vehicle, every lock reached the target.
    out.set_final_lock_state(target_locked ? v1::LOCK_STATE_LOCKED : v1::LOCK_STATE_UNLOCKED);
    out.set_final_lock_state_name(
        config.decode_options.lock_state_names[target_locked ? node::lock_state::kLocked
                                                             : node::lock_state::kUnlocked]);
  }
  out.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - r.received)));
  count(out);
  spdlog::info("command {}: {} ({}) in {} ms{}", out.command_id(),
               command_result_name(out.result()), out.final_lock_state_name(), out.duration_ms(),
               out.reason().empty() ? "" : ": " + out.reason());
  const Micros expires = r.cmd.expires_at;
  const Micros received = r.received;
  // Remove before storing so an observer may already send the next command.
  const std::string id = r.cmd.command_id;
  running.erase(std::remove_if(running.begin(), running.end(),
                               [&](const auto& p) { return p->cmd.command_id == id; }),
                running.end());
  store_result(std::move(out), now, std::max(expires, now + config.rejected_retention), received);
}

}  // namespace fleetgw::command
