// MC actions (issue 13) inside the command service: the pre-flight refusal, the journal entry
// before the first CAN frame, and the one result -- the same guarantees as a lock command. The
// bus side is McActionRunner (mc_actions.cc). Also the gateway's own MC actions (geofences,
// issue 14): the same pre-flight and confirmation, no journal, no result message. A remote
// speed limit is the operator's cap (issue 24): the MC is given the limit in force with it
// (geofence::SpeedAuthority), and a success records the cap in the store's meta table
// (kSpeedCapKey), so it outlives a restart and a slow zone never lifts it.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>

#include "gateway/command/command_service_impl.h"

namespace fleetgw::command {
namespace {

// The stored cap, read once per process before the authority is first used (the store is
// opened before the service; a read error leaves no cap and is logged).
geofence::SpeedAuthority& restored_authority(McActionRunner& mc, storage::Store& store) {
  auto& speed = mc.speed();
  if (mc.cap_restored) return speed;
  mc.cap_restored = true;
  try {
    const auto text = store.meta(kSpeedCapKey);
    if (!text) return speed;
    int kmh = 0;
    const auto [end, ec] = std::from_chars(text->data(), text->data() + text->size(), kmh);
    if (ec != std::errc() || end != text->data() + text->size() || kmh < 1 || kmh > 255) {
      spdlog::error("command: stored speed cap '{}' is not 1..255 km/h; ignored", *text);
      return speed;
    }
    speed.set_operator_cap(kmh);
    spdlog::info("command: operator speed cap {} km/h restored", kmh);
  } catch (const std::exception& e) {
    spdlog::error("command: reading the stored speed cap failed: {}", e.what());
  }
  return speed;
}

}  // namespace

geofence::SpeedAuthority& CommandService::speed_authority() {
  return restored_authority(impl_->mc, impl_->context.store);
}

Disposition CommandService::Impl::on_mc_command(VerifiedCommand cmd, Micros now) {
  const Micros wall_now = wall(now);
  if (cmd.mc.kind == McActionKind::kSpeedLimit) {
    restored_authority(mc, context.store);
    cmd.mc.sets_operator_cap = true;
  }
  if (auto rej = mc.preflight(cmd.mc, !running.empty(), now)) {
    rej->command_id = cmd.command_id;
    rej->command_sha256 = cmd.command_sha256;
    rej->operator_id = cmd.operator_id;
    remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
    return reject(*rej, now, cmd.expires_at);
  }
  // Journal first: after a crash from here on, recover() answers without acting again.
  if (const auto rejected = journal_executing(cmd, now)) return *rejected;
  // The action and key id were matched against the schema and the configuration.
  spdlog::info("command {}: {} accepted (key {})", cmd.command_id, mc_action_name(cmd.mc.kind),
               cmd.key_id);
  const McRequest request = cmd.mc;
  mc_run = McRun{std::move(cmd), now};
  // The runner owns no reference to us beyond this call's lifetime: it is our member.
  mc.start(request, now,
           [this](McOutcome outcome, Micros at) { finish_mc(std::move(outcome), at); });
  return Disposition::kStarted;
}

void CommandService::Impl::finish_mc(McOutcome outcome, Micros now) {
  if (!mc_run) return;
  const McRun run = std::move(*mc_run);
  mc_run.reset();
  v1::CommandResult out;
  out.set_command_id(run.cmd.command_id);
  out.set_command_sha256(run.cmd.command_sha256);
  out.set_operator_id(run.cmd.operator_id);
  out.set_result(outcome.code);
  out.set_reason(std::move(outcome.reason));
  std::optional<int> confirmed_cap;
  if (run.cmd.mc.kind == McActionKind::kSpeedLimit) {
    auto& speed = mc.speed();
    if (outcome.code == v1::COMMAND_RESULT_CODE_SUCCEEDED) {
      // In force at once; stored with the result, in its transaction (store_result notes in
      // limit_in_force when the store refuses it).
      confirmed_cap = static_cast<int>(run.cmd.mc.speed_limit_kmh);
      speed.set_operator_cap(*confirmed_cap);
    }
    if (const auto cap = speed.operator_cap()) {
      outcome.details.set_operator_cap_kmh(static_cast<std::uint32_t>(*cap));
    }
    outcome.details.set_limit_in_force(speed.explain());
  }
  *out.mutable_mc() = std::move(outcome.details);
  out.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - run.received)));
  count(out);
  spdlog::info("command {}: {} {} in {} ms{}", out.command_id(), out.mc().action(),
               command_result_name(out.result()), out.duration_ms(),
               out.reason().empty() ? "" : ": " + out.reason());
  store_result(std::move(out), now, std::max(run.cmd.expires_at, now + config.rejected_retention),
               run.received, confirmed_cap);
}

std::optional<Rejection> CommandService::start_own_mc_action(const McRequest& request, Micros now,
                                                             OwnMcDone done) {
  Impl& s = *impl_;
  if (s.mc_run || s.mc.busy()) {
    Rejection busy;
    busy.reason = RejectReason::kMcBusy;
    busy.detail = "another MC action is running";
    return busy;
  }
  if (auto rej = s.mc.preflight(request, !s.running.empty(), now)) return rej;
  restored_authority(s.mc, s.context.store);
  s.mc.start(request, now, [done = std::move(done)](McOutcome outcome, Micros at) {
    done(outcome.code == v1::COMMAND_RESULT_CODE_SUCCEEDED, std::move(outcome.reason), at);
  });
  return std::nullopt;
}

}  // namespace fleetgw::command
