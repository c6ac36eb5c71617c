// MC actions (issue 13) inside the command service: the pre-flight refusal, the journal entry
// before the first CAN frame, and the one result -- the same guarantees as a lock command. The
// bus side is McActionRunner (mc_actions.cc). Also the gateway's own MC actions (geofences,
// issue 14): the same pre-flight and confirmation, no journal, no result message.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/command/command_service_impl.h"

namespace fleetgw::command {

Disposition CommandService::Impl::on_mc_command(VerifiedCommand cmd, Micros now) {
  const Micros wall_now = wall(now);
  if (auto rej = mc.preflight(cmd.mc, !running.empty(), now)) {
    rej->command_id = cmd.command_id;
    rej->command_sha256 = cmd.command_sha256;
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
  out.set_result(outcome.code);
  out.set_reason(std::move(outcome.reason));
  *out.mutable_mc() = std::move(outcome.details);
  out.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - run.received)));
  count(out);
  spdlog::info("command {}: {} {} in {} ms{}", out.command_id(), out.mc().action(),
               command_result_name(out.result()), out.duration_ms(),
               out.reason().empty() ? "" : ": " + out.reason());
  store_result(std::move(out), now, std::max(run.cmd.expires_at, now + config.rejected_retention),
               run.received);
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
  s.mc.start(request, now, [done = std::move(done)](McOutcome outcome, Micros at) {
    done(outcome.code == v1::COMMAND_RESULT_CODE_SUCCEEDED, std::move(outcome.reason), at);
  });
  return std::nullopt;
}

}  // namespace fleetgw::command
