// The public face of the command service: configuration, construction, start-up recovery,
// purging, and the entry points (see command_service_impl.h for where each part lives).
#include "gateway/command/command_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "gateway/command/command_service_impl.h"
#include "gateway/config/config.h"
#include "gateway/node/messages.h"

namespace fleetgw::command {
namespace {

constexpr Micros kClockSyncEpoch{1'704'067'200'000'000};  // 2024-01-01T00:00:00Z
// The revocation lists in force (Revocations::persisted(): one base64 SignedRevocationList per
// line), in the store's meta table beside the speed cap.
constexpr std::string_view kRevocationsKey = "command.revocations";

InterlockSettings interlock_settings(const CommandServiceConfig& c) {
  return {.rules = c.interlocks,
          .speed_kmh = c.interlock_speed_kmh,
          .motor_window = c.interlock_motor_window,
          .motion_max_age = c.motion_max_age,
          .motion_unknown_blocks = c.motion_unknown_blocks,
          .decode_options = c.decode_options};
}

McActionConfig mc_settings(const CommandServiceConfig& c) {
  McActionConfig m = c.mc;
  m.decode_options = c.decode_options;
  m.confirm_timeout = c.confirm_timeout;
  m.retries = c.retries;
  return m;
}

DiagReaderConfig diag_settings(const CommandServiceConfig& c) {
  DiagReaderConfig d = c.diag;
  d.decode_options = c.decode_options;
  return d;
}

}  // namespace

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
    case node::lock_state::kUnlocking:
      return v1::LOCK_STATE_UNLOCKING;
    case node::lock_state::kLocking:
      return v1::LOCK_STATE_LOCKING;
    case node::lock_state::kUnlockFailed:
    case node::lock_state::kLockFailed:
      return v1::LOCK_STATE_FAULT;
    default:
      return v1::LOCK_STATE_UNSPECIFIED;
  }
}

std::optional<std::string> write_batch(storage::Store& store, const storage::Batch& batch) {
  // Store::write never throws: a disk error comes back in the result.
  const auto written = store.write(batch);
  if (!written.ok()) return written.status().message;
  return std::nullopt;
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
    case Disposition::kBusy:
      return "busy";
  }
  return "unknown";
}

CommandServiceConfig make_command_service_config(const config::Config& c) {
  CommandServiceConfig out;
  out.verifier.vehicle_id = c.vehicle.id;
  out.verifier.trusted_keys = c.command.trusted_keys;
  out.verifier.root_keys = c.command.root_keys;
  out.verifier.groups = c.vehicle.groups;
  out.verifier.clock_skew = Micros(std::int64_t{c.command.clock_skew_s} * 1'000'000);
  out.verifier.lock_kinds = c.protocol.lock_kinds;
  out.decode_options = c.protocol;
  out.interlock_speed_kmh = c.command.interlock_speed_kmh;
  out.interlock_motor_window = Micros(std::int64_t{c.command.interlock_motor_s} * 1'000'000);
  out.confirm_timeout = Micros(std::int64_t{c.command.confirm_timeout_ms} * 1000);
  out.retries = c.command.retries;
  out.mc.settings_limit_is_factory = c.command.mc_settings_limit == "factory";
  return out;
}

// --- Impl: shared helpers, recovery, purging --------------------------------------------------

CommandService::Impl::Impl(CommandServiceConfig c, CommandContext ctx)
    : config(std::move(c)),
      context(std::move(ctx)),
      verifier(config.verifier),
      motion(interlock_settings(config)),
      mc(mc_settings(config), context.node, motion),
      diag(diag_settings(config), context.node),
      capture(context.store) {
  if (config.retries < 0) throw std::invalid_argument("command.retries must be >= 0");
  if (config.confirm_timeout <= Micros(0)) {
    throw std::invalid_argument("command.confirm_timeout must be > 0");
  }
  if (!context.clock_synchronised) context.clock_synchronised = default_clock_synchronised;
  tokens = config.unauthenticated_results_per_minute;
  // Revocations are enforced offline: the lists stored by an earlier run are in force before
  // the first payload (each re-verified against today's root keys).
  try {
    if (const auto stored = context.store.meta(kRevocationsKey)) {
      for (const auto& problem : verifier.restore_revocations(*stored)) {
        spdlog::error("command: {}; not in force", problem);
      }
      if (verifier.revocations().unknown()) {
        spdlog::error(
            "command: delegated keys are refused until a root's revocation list is "
            "received (the stored lists could not be restored)");
      }
      if (const auto v = verifier.revocations().version()) {
        spdlog::info("command: revocation list version {} restored", v);
      }
    }
  } catch (const std::exception& e) {
    // Fail closed: a revoked key must not come back because the store could not be read.
    spdlog::error(
        "command: reading the stored revocation lists failed: {}; delegated keys are refused "
        "until a root's list is received",
        e.what());
    verifier.revocations_unreadable(e.what());
  }
}

void CommandService::Impl::remember(const VerifiedCommand& c, Micros keep_until) {
  if (known.size() >= kMaxKnown && !known.contains(c.command_id)) known.erase(known.begin());
  known[c.command_id] = {c.command_sha256, keep_until};
}

std::string CommandService::Impl::state_name(std::optional<std::uint8_t> raw) const {
  if (!raw) return {};
  const auto& names = config.decode_options.lock_state_names;
  if (*raw < names.size()) return names[*raw];
  return "state_" + std::to_string(*raw);
}

std::string_view CommandService::Impl::kind_of(int k) const {
  return config.verifier.lock_kinds[static_cast<std::size_t>(k)];
}

CommandService::Impl::Running* CommandService::Impl::find_running(std::string_view id) {
  for (auto& r : running) {
    if (r->cmd.command_id == id) return r.get();
  }
  return nullptr;
}

bool CommandService::Impl::executing(std::string_view id) {
  return find_running(id) != nullptr || (mc_run && mc_run->cmd.command_id == id) ||
         (diag_run && diag_run->cmd.command_id == id);
}

// ---------------------------------------------------------------------------------------------

CommandService::CommandService(CommandServiceConfig config, CommandContext context)
    : impl_(std::make_shared<Impl>(std::move(config), std::move(context))) {}

CommandService::~CommandService() = default;

std::size_t CommandService::recover(Micros now) {
  const Impl::WriteScope scope(*impl_);
  std::vector<storage::CommandJournalRow> stuck;
  try {
    std::vector<std::string> ids;
    impl_->context.store.export_table("commands", 0, [&](const nlohmann::json& row) {
      if (row.value("state", "") == kExecuting) ids.push_back(row.value("command_id", ""));
    });
    // The whole entry, digest included (the export shows blobs as hex text).
    for (const auto& id : ids) {
      if (auto entry = impl_->context.store.command(id)) stuck.push_back(std::move(*entry));
    }
  } catch (const std::exception& e) {
    spdlog::error("command: reading the journal at start-up failed: {}", e.what());
  }
  for (const auto& e : stuck) {
    if (!impl_->executing(e.command_id)) impl_->finish_interrupted(e, now);
  }
  return stuck.size();
}

Disposition CommandService::on_payload(std::span<const std::uint8_t> payload, Micros now) {
  const Impl::WriteScope scope(*impl_);
  return impl_->on_payload(payload, now);
}

Disposition CommandService::on_payload(std::string_view payload, Micros now) {
  return on_payload({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, now);
}

Disposition CommandService::answer_busy(std::string_view command_id,
                                        std::string_view command_sha256, Micros now) {
  const Impl::WriteScope scope(*impl_);
  VerifiedCommand cmd;
  cmd.command_id = std::string(command_id);
  cmd.command_sha256 = std::string(command_sha256);
  return impl_->answer_busy(std::move(cmd), now);
}

Disposition CommandService::answer_stopping(std::span<const std::uint8_t> payload, Micros now) {
  const Impl::WriteScope scope(*impl_);
  return impl_->answer_stopping(payload, now);
}

PayloadAuthenticator CommandService::authenticator() const {
  // Its own verifier, built from the same configuration: immutable after construction, so the
  // Paho thread shares no state with this service (which lives on the owner's thread).
  auto verifier = std::make_shared<const CommandVerifier>(impl_->config.verifier);
  return [verifier](std::span<const std::uint8_t> payload) {
    PayloadAuthentication out;
    VerifyResult r = verifier->authenticate(payload);
    if (auto* cmd = std::get_if<VerifiedCommand>(&r)) {
      out.authenticated = true;
      out.command_id = std::move(cmd->command_id);
      out.command_sha256 = std::move(cmd->command_sha256);
    } else if (auto* rej = std::get_if<Rejection>(&r); rej->authenticated) {
      out.authenticated = true;  // wrong_vehicle: signed by a trusted key, refused later
      out.command_id = std::move(rej->command_id);
      out.command_sha256 = std::move(rej->command_sha256);
    }
    return out;
  };
}

void CommandService::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status == motinova::DecodeStatus::kOk && msg.name() == "mc_status") {
    impl_->motion.observe_mc_status(msg, now);
  }
  impl_->mc.on_message(msg, now);
  impl_->diag.on_message(msg, now);
  impl_->capture.on_message(msg, impl_->wall(now).count());
}

void CommandService::tick(Micros now) {
  // Timeouts and retries on the bus (CAN writes, results concluded): no SQLite here.
  impl_->mc.tick(now);
  impl_->diag.tick(now);
}

void CommandService::run(Micros now) {
  Impl& s = *impl_;
  const Impl::WriteScope scope(s);  // writes what the bus side concluded
  if (!s.unjournaled.empty()) s.retry_unjournaled(now);
  s.capture.tick(now);
  s.purge(now);
}

void CommandService::Impl::purge(Micros now) {
  if (now < next_purge) return;
  // Also while the clock is not synchronised: checked again after the interval, not at once.
  next_purge = now + config.purge_interval;
  const Micros wall_now = wall(now);
  if (!context.clock_synchronised(wall_now)) return;
  std::erase_if(known, [wall_now](const auto& kv) { return kv.second.second <= wall_now; });
  try {
    const std::size_t n = context.store.purge_expired_commands(wall_now.count());
    if (n > 0) spdlog::debug("command: forgot {} expired command id(s)", n);
  } catch (const std::exception& e) {
    spdlog::error("command: purging expired command ids failed: {}", e.what());
  }
}

std::optional<Micros> CommandService::next_due(Micros now) const {
  const Impl& s = *impl_;
  if (!s.pending.empty()) return now;
  Micros due = s.next_purge;
  const bool retry = std::any_of(s.unjournaled.begin(), s.unjournaled.end(),
                                 [](const auto& kv) { return !kv.second.awaiting; });
  if (retry) due = std::min(due, s.next_journal_retry);
  if (const auto c = s.capture.next_due()) due = std::min(due, *c);
  return due;
}

bool CommandService::writes_pending() const {
  return !impl_->pending.empty();
}

std::size_t CommandService::take_stored() {
  return std::exchange(impl_->stored_count, 0);
}

std::vector<UnstoredResult> CommandService::take_unstored() {
  return std::exchange(impl_->unstored_out, {});
}

void CommandService::unstored_handed(std::string_view command_id, bool handed) {
  impl_->unstored_handed(command_id, handed);
}

void CommandService::set_result_observer(ResultObserver observer) {
  impl_->observer = std::move(observer);
}

void CommandService::set_lock_guard(LockGuard guard) {
  impl_->lock_guard = std::move(guard);
}

void CommandService::set_unlock_guard(LockGuard guard) {
  impl_->unlock_guard = std::move(guard);
}

RevocationVerdict CommandService::on_revocations(std::span<const std::uint8_t> payload,
                                                 Micros now) {
  Impl& s = *impl_;
  RevocationVerdict verdict = s.verifier.offer_revocations(payload);
  if (!verdict.accepted()) {
    if (verdict.outcome == RevocationOutcome::kRefused) {
      spdlog::warn("command: revocation list refused: {}: {}", verdict.reason, verdict.detail);
    }
    return verdict;
  }
  spdlog::info("command: revocation list {}", verdict.detail);
  const Impl::WriteScope scope(s);
  storage::Batch b;
  b.now_us = now.count();
  b.meta.emplace_back(std::string(kRevocationsKey), s.verifier.revocations().persisted());
  if (const auto error = write_batch(s.context.store, b)) {
    // Enforced all the same: a withdrawn key must not wait for a healthy disk.
    spdlog::error("command: revocation list version {} in force but not stored: {}",
                  verdict.version, *error);
  }
  return verdict;
}

std::uint64_t CommandService::revocation_version() const {
  return impl_->verifier.revocations().version();
}

CommandService::DelegatedDocumentCheck CommandService::delegated_document_check(
    std::string action) const {
  std::weak_ptr<Impl> weak = impl_;
  return [weak, action = std::move(action)](
             const v1::SignedDelegation& delegation, std::string_view signer_key_id,
             std::span<const std::uint8_t> signed_bytes,
             std::span<const std::uint8_t> signature) -> DelegatedCheck {
    const auto impl = weak.lock();
    if (!impl) {
      DelegatedCheck gone;
      gone.problem = DelegationProblem{DelegationRefusal::kInvalid, "the gateway is stopping"};
      return gone;
    }
    // Documents arrive outside the bus timeline: judged by the wall clock (the system's when
    // the runtime gave none).
    const Micros now = impl->context.wall_clock
                           ? impl->context.wall_clock()
                           : std::chrono::duration_cast<Micros>(
                                 std::chrono::system_clock::now().time_since_epoch());
    return check_delegated(delegation, signer_key_id, signed_bytes, signature, action,
                           impl->verifier.identity(), now, impl->context.clock_synchronised(now),
                           impl->verifier.root_keys(), impl->verifier.revocations());
  };
}

bool CommandService::busy() const {
  return !impl_->running.empty() || impl_->mc.busy();
}
std::size_t CommandService::unjournaled() const {
  return impl_->unjournaled.size();
}
const CommandStats& CommandService::stats() const {
  return impl_->stats;
}
const CommandServiceConfig& CommandService::config() const {
  return impl_->config;
}

}  // namespace fleetgw::command
