// A payload's way in: authenticate (one parse), recognise a redelivery or a reused id, judge
// freshness, then the checks that must hold before the first CAN write. And the `busy` answer
// for an authenticated command the uplink's full queue could not take.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/command/command_service_impl.h"
#include "motinova/catalogue.h"

namespace fleetgw::command {

using node::LockTarget;

Disposition CommandService::Impl::on_payload(std::span<const std::uint8_t> payload, Micros now) {
  ++stats.payloads;
  VerifyResult auth = verifier.authenticate(payload);
  // Not authentic: answered (rate limited, bound to the forged bytes) but never journaled and
  // never recorded as seen, so it cannot block or pre-empt the genuine command with that id.
  if (auto* rej = std::get_if<Rejection>(&auth)) return reject(*rej, now, std::nullopt);
  auto& cmd = std::get<VerifiedCommand>(auth);

  if (auto known_answer = answer_known(cmd, now)) return *known_answer;

  const Micros wall_now = wall(now);
  const bool synced = context.clock_synchronised(wall_now);
  const auto seen = [this](std::string_view id, Micros at) {
    try {
      return context.store.command_seen(id, at.count());
    } catch (const std::exception& e) {
      // Unknown counts as seen: executing a possible replay is worse than refusing.
      spdlog::error("command {}: seen-id lookup failed: {}", id, e.what());
      return true;
    }
  };
  // Issue 28: revoked, out of scope or outside its delegation's window. Answered like a payload
  // that failed authentication (bound to the payload, rate limited, never journaled or marked
  // as seen): a withdrawn key must neither fill the journal nor use up a command id.
  if (auto rej = verifier.authorize(cmd, wall_now, synced)) return reject(*rej, now, std::nullopt);
  if (auto rej = verifier.check(cmd, wall_now, synced, seen)) {
    // A replay whose journal entry is gone (purged) gets no new journal row either.
    const bool journal = rej->reason != RejectReason::kReplayed;
    if (journal) remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
    return reject(*rej, now, journal ? std::optional<Micros>(cmd.expires_at) : std::nullopt,
                  !journal);
  }
  if (cmd.diag.requested()) return on_diag_command(std::move(cmd), now);
  if (cmd.mc.kind != McActionKind::kNone) return on_mc_command(std::move(cmd), now);
  if (auto rej = preflight(cmd, now)) {
    remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
    return reject(*rej, now, cmd.expires_at);
  }
  return start(std::move(cmd), now);
}

std::optional<Disposition> CommandService::Impl::answer_known(const VerifiedCommand& cmd,
                                                              Micros now) {
  auto reused_id = [&] {
    // Not journaled again: the journal entry belongs to the first command with this id.
    Rejection rej{RejectReason::kReplayed, "command id already used by a different command",
                  cmd.command_id, true, cmd.command_sha256};
    rej.operator_id = cmd.operator_id;
    return reject(rej, now, std::nullopt, /*always_answer=*/true);
  };

  // Answered while the store refused it: the same answer again, never a second execution.
  if (const auto u = unjournaled.find(cmd.command_id); u != unjournaled.end()) {
    if (u->second.result.command_sha256() != cmd.command_sha256) return reused_id();
    return duplicate_unjournaled(u->second, now);
  }

  // A command we journaled before: never judged (or acted on) a second time.
  std::optional<storage::CommandJournalRow> entry;
  try {
    entry = context.store.command(cmd.command_id);
  } catch (const std::exception& e) {
    ++stats.storage_errors;
    return reject({RejectReason::kStorageError, "journal lookup failed: " + std::string(e.what()),
                   cmd.command_id, true, cmd.command_sha256},
                  now, std::nullopt, /*always_answer=*/true);
  }
  if (entry) {
    const auto it = known.find(cmd.command_id);
    if (it != known.end() && it->second.first != cmd.command_sha256) return reused_id();
    return duplicate(*entry, cmd.command_sha256, now, cmd.operator_id);
  }
  return std::nullopt;
}

// The uplink's queue was full. Nothing is judged beyond the signature (checked on Paho's
// thread), nothing journaled or marked as seen: the operator may send the same command again.
// Never rate limited: each one is an authenticated command, and its sender waits for an answer.
Disposition CommandService::Impl::answer_busy(VerifiedCommand cmd, Micros now) {
  ++stats.payloads;
  return answer_not_run(std::move(cmd), now,
                        "busy: the gateway's command queue was full; not executed and not "
                        "recorded as used, send it again",
                        "busy (command queue full)");
}

// Issue 24: the service stops with commands still in the uplink's queue (or arriving while the
// outbox drains). Running them is no longer possible (the bus is stopped), dropping them left
// their senders without any result.
Disposition CommandService::Impl::answer_stopping(std::span<const std::uint8_t> payload,
                                                  Micros now) {
  ++stats.payloads;
  VerifyResult auth = verifier.authenticate(payload);
  if (auto* rej = std::get_if<Rejection>(&auth)) return reject(*rej, now, std::nullopt);
  return answer_not_run(std::get<VerifiedCommand>(std::move(auth)), now,
                        "shutting_down: the gateway stopped before running it; not executed and "
                        "not recorded as used, send it again",
                        "shutting_down (arrived while the gateway stopped)");
}

Disposition CommandService::Impl::answer_not_run(VerifiedCommand cmd, Micros now,
                                                 std::string reason, std::string_view why_logged) {
  if (auto known_answer = answer_known(cmd, now)) return *known_answer;
  v1::CommandResult r;
  r.set_command_id(cmd.command_id);
  r.set_command_sha256(cmd.command_sha256);
  r.set_operator_id(cmd.operator_id);
  r.set_result(v1::COMMAND_RESULT_CODE_REJECTED);
  r.set_reason(std::move(reason));
  count(r);
  spdlog::warn("command {}: rejected: {}", cmd.command_id, why_logged);
  store_result(std::move(r), now, std::nullopt, std::nullopt);
  return Disposition::kBusy;
}

std::optional<Rejection> CommandService::Impl::preflight(const VerifiedCommand& cmd, Micros now) {
  auto fail = [&](RejectReason r, std::string detail) {
    Rejection out{r, std::move(detail), cmd.command_id, true, cmd.command_sha256};
    out.operator_id = cmd.operator_id;
    return out;
  };
  if (context.node.shutdown_running()) {
    return fail(RejectReason::kShuttingDown, "the gateway is shutting the bike down");
  }
  const auto indices = lock_indices(cmd);
  for (const int k : indices) {
    if (!context.node.registry().online(motinova::lock_node(k))) {
      return fail(RejectReason::kLockOffline, "the " + std::string(kind_of(k)) + " lock (node " +
                                                  std::to_string(7 + k) + ") is offline");
    }
  }
  for (const int k : indices) {
    const bool in_use = std::any_of(running.begin(), running.end(), [k](const auto& r) {
      return std::any_of(r->steps.begin(), r->steps.end(),
                         [k](const Step& s) { return s.lock_index == k; });
    });
    if (in_use || context.node.locks().busy(k)) {
      return fail(RejectReason::kLockBusy,
                  "the " + std::string(kind_of(k)) + " lock is executing another command");
    }
  }
  if (cmd.whole_vehicle && !running.empty()) {
    return fail(RejectReason::kLockBusy, "another command is executing");
  }
  for (const int k : indices) {
    if (auto rej = interlock(k, cmd.target, now)) {
      rej->command_id = cmd.command_id;
      rej->command_sha256 = cmd.command_sha256;
      rej->operator_id = cmd.operator_id;
      return rej;
    }
  }
  // Last: only a lock that would otherwise run is judged (and reported) by the geofence.
  if (lock_guard && cmd.target == LockTarget::kLocked) {
    const bool ride_ending = cmd.whole_vehicle || kind_of(cmd.lock_index) == "frame" ||
                             kind_of(cmd.lock_index) == "wheel";
    if (auto detail = lock_guard(ride_ending, now)) {
      return fail(RejectReason::kNoParkingZone, std::move(*detail));
    }
  }
  if (unlock_guard && cmd.target == LockTarget::kUnlocked) {
    const bool ride_starting = cmd.whole_vehicle || kind_of(cmd.lock_index) == "frame" ||
                               kind_of(cmd.lock_index) == "wheel";
    if (auto detail = unlock_guard(ride_starting, now)) {
      return fail(RejectReason::kNoStartZone, std::move(*detail));
    }
  }
  return std::nullopt;
}

std::optional<Rejection> CommandService::Impl::interlock(int k, LockTarget target, Micros now) {
  return motion.check(kind_of(k), target, context.node.registry(), now);
}

// Locks a command acts on, in execution order.
std::vector<int> CommandService::Impl::lock_indices(const VerifiedCommand& cmd) const {
  if (!cmd.whole_vehicle) return {cmd.lock_index};
  const auto& kinds = config.verifier.lock_kinds;
  const auto& order = config.vehicle_lock_order;
  auto rank = [&](int k) {
    const auto it = std::find(order.begin(), order.end(), kinds[static_cast<std::size_t>(k)]);
    return it == order.end() ? -1 : static_cast<int>(it - order.begin());
  };
  std::vector<int> out;
  for (int k = 0; k < motinova::kLockCount; ++k) {
    if (!kinds[static_cast<std::size_t>(k)].empty()) out.push_back(k);
  }
  std::stable_sort(out.begin(), out.end(), [&](int a, int b) { return rank(a) < rank(b); });
  if (cmd.target == LockTarget::kUnlocked) std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace fleetgw::command
