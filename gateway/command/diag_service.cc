// Diagnostic reads (issue 29) inside the command service: the pre-flight refusals, the journal
// entry before the first CAN frame, and the one result -- the same guarantees as a lock command
// or an MC action. The bus side is DiagReader (diag_reader.cc); the lifetime records seen on
// the bus are DiagCapture's (diag_capture.cc).
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/command/command_service_impl.h"

namespace fleetgw::command {

Disposition CommandService::Impl::on_diag_command(VerifiedCommand cmd, Micros now) {
  const Micros wall_now = wall(now);
  auto refuse = [&](RejectReason reason, std::string detail) {
    Rejection rej{reason, std::move(detail), cmd.command_id, true, cmd.command_sha256};
    rej.operator_id = cmd.operator_id;
    remember(cmd, std::max(cmd.expires_at, wall_now + config.rejected_retention));
    return reject(rej, now, cmd.expires_at);
  };
  const bool lock = cmd.diag.block == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL;
  const DiagBlockSpec* found = find_diag_block(cmd.diag.block);
  if (found == nullptr || (lock && cmd.lock_index < 0)) {
    return refuse(RejectReason::kMalformed, "not a diagnostic block");  // the verifier's job
  }
  const DiagBlockSpec spec = lock ? lock_model_block(cmd.lock_index) : *found;
  if (!cmd.diag.last_captured) {
    if (context.node.shutdown_running()) {
      return refuse(RejectReason::kShuttingDown, "the gateway is shutting the bike down");
    }
    if (diag_run || diag.busy()) {
      return refuse(RejectReason::kDiagBusy, "another diagnostic read is running");
    }
    // An MC action confirms from the MC's own answers (0x5408): a read of ours in between
    // could be taken for one, so the MC is asked one thing at a time.
    if (spec.node == motinova::Node::kMc && (mc_run || mc.busy())) {
      return refuse(RejectReason::kMcBusy, "an MC action is executing");
    }
    if (lock && context.node.locks().busy(cmd.lock_index)) {
      return refuse(RejectReason::kLockBusy,
                    "the " + std::string(kind_of(cmd.lock_index)) + " lock is executing a command");
    }
  }
  // Journal first, as for every command: one result per id, a redelivery never reads twice.
  if (const auto rejected = journal_executing(cmd, now)) return *rejected;
  spdlog::info("command {}: diagnostic read {}{} accepted (key {})", cmd.command_id, spec.name,
               cmd.diag.last_captured ? " (last captured)" : "", cmd.key_id);
  const bool captured = cmd.diag.last_captured;
  diag_run = McRun{std::move(cmd), now};
  if (captured) {
    finish_diag(read_captured(spec), now);
    return Disposition::kStarted;
  }
  diag.start(
      spec, now, [this](Micros heard, Micros at) { return (wall(at) - (at - heard)).count(); },
      [this](DiagOutcome outcome, Micros at) { finish_diag(std::move(outcome), at); });
  return Disposition::kStarted;
}

DiagOutcome CommandService::Impl::read_captured(const DiagBlockSpec& spec) const {
  DiagOutcome out;
  out.details.set_block(std::string(spec.name));
  out.details.set_node(std::string(motinova::node_name(spec.node)));
  out.details.set_source("captured");
  for (const auto& step : spec.steps) {
    const DiagCapture::Record* rec = capture.latest(step.answer_name);
    if (rec == nullptr) {
      if (step.optional && out.details.messages_size() > 0) {
        out.details.set_note(std::string(step.answer_name) + " never seen on the bus");
        continue;
      }
      out.code = v1::COMMAND_RESULT_CODE_FAILED;
      out.reason = "not_captured: no " + std::string(step.answer_name) +
                   " record seen on the bus yet; read it without last_captured";
      return out;
    }
    decode_diag_message(rec->frame, diag.config().decode_options, rec->heard_wall_us,
                        *out.details.add_messages());
  }
  out.code = v1::COMMAND_RESULT_CODE_SUCCEEDED;
  return out;
}

void CommandService::Impl::finish_diag(DiagOutcome outcome, Micros now) {
  if (!diag_run) return;
  const McRun run = std::move(*diag_run);
  diag_run.reset();
  v1::CommandResult out;
  out.set_command_id(run.cmd.command_id);
  out.set_command_sha256(run.cmd.command_sha256);
  out.set_operator_id(run.cmd.operator_id);
  out.set_result(outcome.code);
  out.set_reason(std::move(outcome.reason));
  *out.mutable_diagnostic() = std::move(outcome.details);
  out.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - run.received)));
  count(out);
  spdlog::info("command {}: diagnostic read {} {} in {} ms{}", out.command_id(),
               out.diagnostic().block(), command_result_name(out.result()), out.duration_ms(),
               out.reason().empty() ? "" : ": " + out.reason());
  store_result(std::move(out), now, std::max(run.cmd.expires_at, now + config.rejected_retention),
               run.received);
}

}  // namespace fleetgw::command
