#include "gateway/command/command_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>

#include "fleetgw/v1/command.pb.h"
#include "gateway/config/config.h"
#include "gateway/domain/domain_trackers.h"
#include "gateway/node/messages.h"
#include "motinova/catalogue.h"
#include "storage/store.h"

namespace fleetgw::command {
namespace {

using node::LockOutcome;
using node::LockTarget;

constexpr std::string_view kExecuting = "executing";
constexpr Micros kClockSyncEpoch{1'704'067'200'000'000};  // 2024-01-01T00:00:00Z

std::int64_t to_ms(Micros d) {
  return std::max<std::int64_t>(0, d.count() / 1000);
}

v1::LockState proto_state(std::optional<std::uint8_t> raw) {
  if (!raw) return v1::LOCK_STATE_UNSPECIFIED;
  switch (*raw) {
    case node::lock_state::kUnlocked:
      return v1::LOCK_STATE_UNLOCKED;
    case node::lock_state::kLocked:
      return v1::LOCK_STATE_LOCKED;
    case node::lock_state::kUnlockFailed:
    case node::lock_state::kLockFailed:
      return v1::LOCK_STATE_FAULT;
    default:
      return v1::LOCK_STATE_UNSPECIFIED;
  }
}

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

v1::CommandResultCode code_from_name(std::string_view s) {
  if (s == "succeeded") return v1::COMMAND_RESULT_CODE_SUCCEEDED;
  if (s == "failed") return v1::COMMAND_RESULT_CODE_FAILED;
  if (s == "timeout") return v1::COMMAND_RESULT_CODE_TIMEOUT;
  if (s == "rejected") return v1::COMMAND_RESULT_CODE_REJECTED;
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

storage::Bytes to_bytes(const std::string& s) {
  return storage::Bytes(s.begin(), s.end());
}

}  // namespace

std::map<std::string, InterlockRule> default_interlocks() {
  return {
      {"frame", {.block_lock_while_moving = true}},
      {"wheel", {.block_lock_while_moving = true}},
      {"rear_wheel", {.block_lock_while_moving = true}},
      // A steering lock engaging at speed is a crash.
      {"steering", {.block_lock_while_moving = true}},
      {"battery", {.block_unlock_while_moving = true}},
  };
}

bool default_clock_synchronised(Micros now) {
  return now >= kClockSyncEpoch;
}

std::string_view disposition_name(Disposition d) {
  switch (d) {
    case Disposition::kRejected:
      return "rejected";
    case Disposition::kStarted:
      return "started";
    case Disposition::kDuplicateInProgress:
      return "duplicate_in_progress";
    case Disposition::kDuplicateAnswered:
      return "duplicate_answered";
    case Disposition::kDropped:
      return "dropped";
  }
  return "unknown";
}

CommandServiceConfig make_command_service_config(const config::Config& c) {
  CommandServiceConfig out;
  out.verifier.vehicle_id = c.vehicle.id;
  out.verifier.trusted_keys = c.command.trusted_keys;
  out.verifier.clock_skew = Micros(std::int64_t{c.command.clock_skew_s} * 1'000'000);
  out.verifier.lock_kinds = c.protocol.lock_kinds;
  out.decode_options = c.protocol;
  out.interlock_speed_kmh = c.command.interlock_speed_kmh;
  out.interlock_motor_window = Micros(std::int64_t{c.command.interlock_motor_s} * 1'000'000);
  out.confirm_timeout = Micros(std::int64_t{c.command.confirm_timeout_ms} * 1000);
  out.retries = c.command.retries;
  return out;
}

// ---------------------------------------------------------------------------------------------

struct CommandService::Impl : std::enable_shared_from_this<CommandService::Impl> {
  struct Step {
    int lock_index = 0;
    v1::LockActionResult result;
    int attempts = 0;
    int commands_sent = 0;
    Micros started{0};
    Micros attempt_started{0};
  };
  struct Running {
    VerifiedCommand cmd;
    Micros received{0};
    std::vector<Step> steps;
    std::size_t next = 0;  // index of the step to run next / running
    bool broadcast_sent = false;
  };

  Impl(CommandServiceConfig c, CommandContext ctx)
      : config(std::move(c)), context(std::move(ctx)), verifier(config.verifier) {
    if (config.retries < 0) throw std::invalid_argument("command.retries must be >= 0");
    if (config.confirm_timeout <= Micros(0)) {
      throw std::invalid_argument("command.confirm_timeout must be > 0");
    }
    if (!context.clock_synchronised) context.clock_synchronised = default_clock_synchronised;
    tokens = config.unauthenticated_results_per_minute;
  }

  CommandServiceConfig config;
  CommandContext context;
  CommandVerifier verifier;
  std::vector<std::unique_ptr<Running>> running;
  CommandStats stats;
  ResultObserver observer;
  // Motion: latest mc_status readings (fed by on_message and the registry's snapshot).
  std::optional<Micros> last_rpm_positive;
  std::optional<Micros> last_motion_reading;
  double last_speed_kmh = 0;
  // Rate limit for results not tied to a new authenticated command (token bucket per minute).
  double tokens = 0;
  Micros tokens_at{0};
  Micros next_purge{0};
  // Signed bytes of the commands journaled by this process, until they expire: a command that
  // reuses a journaled id with different content is not a redelivery but a different command
  // (backend bug or id reuse) and is rejected as "replayed" instead of getting the other
  // command's result. Authenticated commands only, so an attacker cannot grow it.
  std::map<std::string, std::pair<std::string, Micros>, std::less<>> known;
  static constexpr std::size_t kMaxKnown = 10'000;

  Micros wall(Micros now) const { return context.wall_clock ? context.wall_clock() : now; }

  void remember(const VerifiedCommand& c, Micros keep_until) {
    if (known.size() >= kMaxKnown) known.erase(known.begin());
    known[c.command_id] = {c.command_bytes, keep_until};
  }

  std::string state_name(std::optional<std::uint8_t> raw) const {
    if (!raw) return {};
    const auto& names = config.decode_options.lock_state_names;
    if (*raw < names.size()) return names[*raw];
    return "state_" + std::to_string(*raw);
  }

  std::string_view kind_of(int k) const {
    return config.verifier.lock_kinds[static_cast<std::size_t>(k)];
  }

  // --- rate limit --------------------------------------------------------------------------

  bool take_token(Micros now) {
    const double per_minute = config.unauthenticated_results_per_minute;
    if (per_minute <= 0) return false;
    if (now > tokens_at) {
      tokens = std::min(
          per_minute, tokens + per_minute * static_cast<double>((now - tokens_at).count()) / 60e6);
      tokens_at = now;
    }
    if (tokens < 1) return false;
    tokens -= 1;
    return true;
  }

  // --- motion ------------------------------------------------------------------------------

  void observe_mc_status(const motinova::DecodedMessage& msg, Micros at) {
    const auto speed = msg.number("speed_kmh");
    const auto rpm = msg.number("motor_rpm");
    if (!speed && !rpm) return;
    if (!last_motion_reading || at >= *last_motion_reading) {
      last_motion_reading = at;
      last_speed_kmh = speed.value_or(0);
    }
    if (rpm && *rpm > 0 && (!last_rpm_positive || at > *last_rpm_positive)) last_rpm_positive = at;
  }

  // nullopt: unknown (no recent mc_status).
  std::optional<bool> moving(Micros now) {
    // The registry keeps the MC's latest mc_status even when on_message is not wired.
    const auto& mc = context.node.registry().node(motinova::Node::kMc);
    if (const auto* snap = mc.find(node::ids::kMcBroadcast, 0x10)) {
      motinova::DecodedMessage decoded;
      motinova::decode(snap->frame, motinova::Catalogue::standard(), config.decode_options,
                       decoded);
      if (decoded.status == motinova::DecodeStatus::kOk) observe_mc_status(decoded, snap->received);
    }
    if (last_rpm_positive && now - *last_rpm_positive <= config.interlock_motor_window) return true;
    if (!last_motion_reading || now - *last_motion_reading > config.motion_max_age) {
      return std::nullopt;
    }
    return last_speed_kmh > config.interlock_speed_kmh;
  }

  // The interlock refusing `target` on lock k right now, if any.
  std::optional<Rejection> interlock(int k, LockTarget target, Micros now) {
    const auto it = config.interlocks.find(std::string(kind_of(k)));
    if (it == config.interlocks.end()) return std::nullopt;
    const bool guarded = target == LockTarget::kLocked ? it->second.block_lock_while_moving
                                                       : it->second.block_unlock_while_moving;
    if (!guarded) return std::nullopt;
    const auto m = moving(now);
    if (m && !*m) return std::nullopt;
    const std::string what = std::string(target == LockTarget::kLocked ? "lock" : "unlock") +
                             " the " + std::string(kind_of(k)) + " lock";
    if (!m) {
      if (!config.motion_unknown_blocks) return std::nullopt;
      return Rejection{RejectReason::kInterlockMotionUnknown,
                       "will not " + what + ": no recent mc_status, motion unknown",
                       {},
                       true};
    }
    return Rejection{RejectReason::kInterlockMoving,
                     "will not " + what + " while the bike moves (speed " +
                         fmt::format("{:.1f}", last_speed_kmh) + " km/h or motor turning within " +
                         std::to_string(config.interlock_motor_window.count() / 1'000'000) + " s)",
                     {},
                     true};
  }

  // --- storage -----------------------------------------------------------------------------

  // Stores the result (and the journal's final state when `journal_expires` is set) in one
  // transaction and tells the observer. Returns false if the store refused.
  bool store_result(const v1::CommandResult& r, Micros now, std::optional<Micros> journal_expires,
                    std::optional<Micros> received) {
    storage::Batch b;
    b.now_us = now.count();
    const std::string payload = r.SerializeAsString();
    if (!r.command_id().empty()) {
      storage::CommandResult row;
      row.command_id = r.command_id();
      row.ts_us = now.count();
      row.result = std::string(command_result_name(r.result()));
      row.reason = r.reason();
      row.final_state = r.final_lock_state_name();
      row.duration_ms = static_cast<std::int64_t>(r.duration_ms());
      b.command_results.push_back({std::move(row), to_bytes(payload)});
    } else {
      // No usable id: the backend still learns that junk arrives, but there is no row to key.
      b.messages.push_back({storage::OutboxKind::kCommandResult,
                            static_cast<int>(storage::OutboxPriority::kCommandResult),
                            to_bytes(payload)});
    }
    if (journal_expires) {
      b.commands.push_back({r.command_id(), received.value_or(now).count(),
                            std::string(command_result_name(r.result())),
                            journal_expires->count()});
    }
    if (const auto written = context.store.write(b); !written.ok()) {
      ++stats.storage_errors;
      spdlog::error("command {}: result {} could not be stored: {}", r.command_id(),
                    command_result_name(r.result()), written.error->message);
      return false;
    }
    if (observer) observer(r, false);
    return true;
  }

  void count(const v1::CommandResult& r) {
    switch (r.result()) {
      case v1::COMMAND_RESULT_CODE_SUCCEEDED:
        ++stats.succeeded;
        break;
      case v1::COMMAND_RESULT_CODE_FAILED:
        ++stats.failed;
        break;
      case v1::COMMAND_RESULT_CODE_TIMEOUT:
        ++stats.timed_out;
        break;
      case v1::COMMAND_RESULT_CODE_REJECTED:
        ++stats.rejected;
        ++stats.rejections[r.reason().substr(0, r.reason().find(':'))];
        break;
      default:
        break;
    }
  }

  Disposition reject(const Rejection& rej, Micros now, std::optional<Micros> expires,
                     bool always_answer = false) {
    v1::CommandResult r;
    r.set_command_id(rej.command_id);
    r.set_result(v1::COMMAND_RESULT_CODE_REJECTED);
    r.set_reason(std::string(reject_reason_name(rej.reason)) + ": " + rej.detail);
    count(r);
    spdlog::warn("command {}: rejected: {}", rej.command_id.empty() ? "<no id>" : rej.command_id,
                 r.reason());
    // Authenticated rejections are journaled (one answer per id, even on redelivery) and always
    // answered; anything else only while the rate limit allows.
    const bool journal = rej.authenticated && expires.has_value() && !rej.command_id.empty();
    if (!journal && !always_answer && !take_token(now)) {
      ++stats.results_dropped;
      return Disposition::kDropped;
    }
    std::optional<Micros> keep;
    if (journal) keep = std::max(*expires, wall(now) + config.rejected_retention);
    store_result(r, now, keep, now);
    return Disposition::kRejected;
  }

  // --- duplicates ---------------------------------------------------------------------------

  Running* find_running(std::string_view id) {
    for (auto& r : running) {
      if (r->cmd.command_id == id) return r.get();
    }
    return nullptr;
  }

  Disposition duplicate(const storage::CommandJournalEntry& entry, Micros now) {
    ++stats.duplicates;
    if (entry.state == kExecuting) {
      if (find_running(entry.command_id) != nullptr) {
        spdlog::info("command {}: duplicate delivery while executing; ignored", entry.command_id);
        return Disposition::kDuplicateInProgress;
      }
      // Journaled by an earlier run that did not finish (recover() not called yet).
      finish_interrupted(entry, now);
      return Disposition::kDuplicateAnswered;
    }
    if (!take_token(now)) {
      ++stats.results_dropped;
      return Disposition::kDropped;
    }
    // The stored result, queued again (a message without a new row: still one result per id).
    v1::CommandResult r;
    r.set_command_id(entry.command_id);
    r.set_result(code_from_name(entry.state));
    bool found = false;
    context.store.export_table("command_results", entry.received_us,
                               [&](const nlohmann::json& row) {
                                 if (found || row.value("command_id", "") != entry.command_id) {
                                   return;
                                 }
                                 found = true;
                                 r.set_result(code_from_name(row.value("result", "")));
                                 r.set_reason(row.value("reason", ""));
                                 r.set_final_lock_state_name(row.value("final_state", ""));
                                 r.set_duration_ms(row.value("duration_ms", std::uint64_t{0}));
                               });
    const auto& names = config.decode_options.lock_state_names;
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (!r.final_lock_state_name().empty() && names[i] == r.final_lock_state_name()) {
        r.set_final_lock_state(proto_state(static_cast<std::uint8_t>(i)));
      }
    }
    storage::Batch b;
    b.now_us = now.count();
    b.messages.push_back({storage::OutboxKind::kCommandResult,
                          static_cast<int>(storage::OutboxPriority::kCommandResult),
                          to_bytes(r.SerializeAsString())});
    if (const auto written = context.store.write(b); !written.ok()) {
      ++stats.storage_errors;
      spdlog::error("command {}: re-sending the stored result failed: {}", entry.command_id,
                    written.error->message);
    }
    spdlog::info("command {}: duplicate delivery; stored result '{}' queued again",
                 entry.command_id, command_result_name(r.result()));
    if (observer) observer(r, true);
    return Disposition::kDuplicateAnswered;
  }

  void finish_interrupted(const storage::CommandJournalEntry& entry, Micros now) {
    v1::CommandResult r;
    r.set_command_id(entry.command_id);
    r.set_result(v1::COMMAND_RESULT_CODE_TIMEOUT);
    r.set_reason(
        "interrupted_by_restart: the gateway stopped before the lock confirmed; not actuated "
        "again");
    r.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - Micros(entry.received_us))));
    count(r);
    ++stats.recovered;
    spdlog::warn("command {}: {}", entry.command_id, r.reason());
    store_result(r, now, Micros(entry.expires_at_us), Micros(entry.received_us));
  }

  // --- payloads ------------------------------------------------------------------------------

  Disposition on_payload(std::span<const std::uint8_t> payload, Micros now) {
    ++stats.payloads;
    VerifyResult auth = verifier.authenticate(payload);
    if (auto* rej = std::get_if<Rejection>(&auth)) return reject(*rej, now, std::nullopt);
    auto& cmd = std::get<VerifiedCommand>(auth);

    // A command we journaled before: never judged (or acted on) a second time.
    std::optional<storage::CommandJournalEntry> entry;
    try {
      entry = context.store.command(cmd.command_id);
    } catch (const std::exception& e) {
      return reject({RejectReason::kStorageError, e.what(), cmd.command_id, false}, now,
                    std::nullopt);
    }
    if (entry) {
      const auto it = known.find(cmd.command_id);
      if (it != known.end() && it->second.first != cmd.command_bytes) {
        // Not journaled again: the journal entry belongs to the first command with this id.
        return reject({RejectReason::kReplayed, "command id already used by a different command",
                       cmd.command_id, true},
                      now, std::nullopt, /*always_answer=*/true);
      }
      return duplicate(*entry, now);
    }

    const Micros wall_now = wall(now);
    const bool synced = context.clock_synchronised(wall_now);
    const auto seen = [this](std::string_view id, Micros at) {
      return context.store.command_seen(id, at.count());
    };
    if (auto rej = verifier.check(cmd, wall_now, synced, seen)) {
      // A replay whose journal entry is gone (purged) gets no new journal row either.
      const bool journal = rej->reason != RejectReason::kReplayed;
      if (journal) remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
      return reject(*rej, now, journal ? std::optional<Micros>(cmd.expires_at) : std::nullopt,
                    !journal);
    }
    if (auto rej = preflight(cmd, now)) {
      remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
      return reject(*rej, now, cmd.expires_at);
    }
    return start(std::move(cmd), now);
  }

  // Everything that must hold before the first CAN write, besides verification.
  std::optional<Rejection> preflight(const VerifiedCommand& cmd, Micros now) {
    auto fail = [&](RejectReason r, std::string detail) {
      return Rejection{r, std::move(detail), cmd.command_id, true};
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
        return rej;
      }
    }
    return std::nullopt;
  }

  // Locks a command acts on, in execution order.
  std::vector<int> lock_indices(const VerifiedCommand& cmd) const {
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

  Disposition start(VerifiedCommand cmd, Micros now) {
    // The journal entry is on disk before anything is written to the bus: after a crash from
    // here on, recover() knows this command may have acted and never acts on it again.
    storage::Batch b;
    b.now_us = now.count();
    b.commands.push_back(
        {cmd.command_id, now.count(), std::string(kExecuting), cmd.expires_at.count()});
    if (const auto written = context.store.write(b); !written.ok()) {
      ++stats.storage_errors;
      spdlog::error("command {}: journal write failed: {}", cmd.command_id, written.error->message);
      return reject({RejectReason::kStorageError, "journal write failed", cmd.command_id, false},
                    now, std::nullopt);
    }
    ++stats.accepted;
    remember(cmd, std::max(cmd.expires_at, wall(now) + config.rejected_retention));
    auto run = std::make_unique<Running>();
    run->received = now;
    for (const int k : lock_indices(cmd)) {
      Step s;
      s.lock_index = k;
      s.result.set_lock_kind(std::string(kind_of(k)));
      run->steps.push_back(std::move(s));
    }
    run->cmd = std::move(cmd);
    spdlog::info("command {}: {} {} accepted (key {})", run->cmd.command_id,
                 node::lock_target_name(run->cmd.target) == "locked" ? "lock" : "unlock",
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
  void advance(Running& r, Micros now) {
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
  bool attempt(Running& r, Step& s, Micros now) {
    ++s.attempts;
    s.attempt_started = now;
    if (context.trackers != nullptr) {
      context.trackers->expect_lock_command(motinova::lock_node(s.lock_index), r.cmd.command_id,
                                            now);
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

  void on_lock_result(const std::string& id, const node::LockResult& res) {
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
                   kind_of(s.lock_index), to_ms(config.confirm_timeout), s.attempts,
                   config.retries);
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

  void finish(Running& r, Micros now) {
    v1::CommandResult out;
    out.set_command_id(r.cmd.command_id);
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
    store_result(out, now, std::max(expires, now + config.rejected_retention), received);
  }

  std::size_t recover(Micros now) {
    std::vector<storage::CommandJournalEntry> stuck;
    context.store.export_table("commands", 0, [&](const nlohmann::json& row) {
      if (row.value("state", "") != kExecuting) return;
      stuck.push_back({row.value("command_id", ""), row.value("received_us", std::int64_t{0}),
                       std::string(kExecuting), row.value("expires_at_us", std::int64_t{0})});
    });
    for (const auto& e : stuck) {
      if (find_running(e.command_id) == nullptr) finish_interrupted(e, now);
    }
    return stuck.size();
  }

  void tick(Micros now) {
    const Micros wall_now = wall(now);
    if (now >= next_purge && context.clock_synchronised(wall_now)) {
      next_purge = now + config.purge_interval;
      std::erase_if(known, [wall_now](const auto& kv) { return kv.second.second <= wall_now; });
      try {
        const std::size_t n = context.store.purge_expired_commands(wall_now.count());
        if (n > 0) spdlog::debug("command: forgot {} expired command id(s)", n);
      } catch (const std::exception& e) {
        spdlog::error("command: purging expired command ids failed: {}", e.what());
      }
    }
  }
};

// ---------------------------------------------------------------------------------------------

CommandService::CommandService(CommandServiceConfig config, CommandContext context)
    : impl_(std::make_shared<Impl>(std::move(config), std::move(context))) {}

CommandService::~CommandService() = default;

std::size_t CommandService::recover(Micros now) {
  return impl_->recover(now);
}

Disposition CommandService::on_payload(std::span<const std::uint8_t> payload, Micros now) {
  return impl_->on_payload(payload, now);
}

Disposition CommandService::on_payload(std::string_view payload, Micros now) {
  return impl_->on_payload({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()},
                           now);
}

void CommandService::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status == motinova::DecodeStatus::kOk && msg.name() == "mc_status") {
    impl_->observe_mc_status(msg, now);
  }
}

void CommandService::tick(Micros now) {
  impl_->tick(now);
}

void CommandService::set_result_observer(ResultObserver observer) {
  impl_->observer = std::move(observer);
}

bool CommandService::busy() const {
  return !impl_->running.empty();
}
const CommandStats& CommandService::stats() const {
  return impl_->stats;
}
const CommandServiceConfig& CommandService::config() const {
  return impl_->config;
}

}  // namespace fleetgw::command
