// Results: every command's one answer, stored with the journal's final state in one
// transaction, or -- when the store refuses -- published unstored and journaled later.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/command/command_service_impl.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::command {
namespace {

v1::CommandResultCode code_from_name(std::string_view s) {
  if (s == "succeeded") return v1::COMMAND_RESULT_CODE_SUCCEEDED;
  if (s == "failed") return v1::COMMAND_RESULT_CODE_FAILED;
  if (s == "timeout") return v1::COMMAND_RESULT_CODE_TIMEOUT;
  if (s == "rejected") return v1::COMMAND_RESULT_CODE_REJECTED;
  return v1::COMMAND_RESULT_CODE_UNSPECIFIED;
}

storage::Bytes to_bytes(const std::string& s) {
  return storage::Bytes(s.begin(), s.end());
}

// Protobuf refuses to serialize a string field that is not UTF-8; a reason must never be the
// reason a result is lost. Everything we put in a reason is valid already; this is the net.
void ensure_utf8(v1::CommandResult& r) {
  if (!common::is_valid_utf8(r.reason())) r.set_reason(common::valid_utf8(r.reason()));
  for (auto& l : *r.mutable_locks()) {
    if (!common::is_valid_utf8(l.reason())) l.set_reason(common::valid_utf8(l.reason()));
  }
}

storage::CommandResultRow row_of(const v1::CommandResult& r, Micros at) {
  storage::CommandResultRow row;
  row.command_id = r.command_id();
  row.ts_us = at.count();
  row.result = std::string(command_result_name(r.result()));
  row.reason = r.reason();
  row.final_state = r.final_lock_state_name();
  row.duration_ms = static_cast<std::int64_t>(r.duration_ms());
  return row;
}

storage::CommandJournalRow journal_of(const v1::CommandResult& r, Micros received, Micros expires) {
  return {r.command_id(), received.count(), std::string(command_result_name(r.result())),
          expires.count(), r.command_sha256()};
}

}  // namespace

// Stores the result -- with the journal's final state when `journal_expires` is set (a row in
// command_results, keyed by the id), else as an outbox message only -- in one transaction, tells
// the observer and counts it for take_stored(). When the store refuses, answers unstored
// instead. Outside a WriteScope (the bus side: a confirmation inside the transport's read
// handler) the result only waits in `pending` for the next scope.
void CommandService::Impl::store_result(v1::CommandResult r, Micros now,
                                        std::optional<Micros> journal_expires,
                                        std::optional<Micros> received,
                                        std::optional<int> speed_cap) {
  if (!writing) {
    pending.push_back({std::move(r), now, journal_expires, received, speed_cap});
    return;
  }
  ensure_utf8(r);
  r.set_stored(true);
  const std::string payload = r.SerializeAsString();
  const bool journal = journal_expires.has_value() && !r.command_id().empty();
  storage::Batch b;
  b.now_us = now.count();
  if (journal) {
    b.command_results.push_back({row_of(r, now), to_bytes(payload)});
    b.commands.push_back(journal_of(r, received.value_or(now), *journal_expires));
  } else {
    // Not about a journaled command (not authentic, a reused id...): the backend still learns
    // of it, but it gets no row that could be mistaken for the answer to that id.
    b.messages.push_back({storage::OutboxKind::kCommandResult,
                          static_cast<int>(storage::OutboxPriority::kCommandResult),
                          to_bytes(payload)});
  }
  // The operator's cap is recorded with the result that confirms it (command_mc.cc).
  if (speed_cap) b.meta.emplace_back(std::string(kSpeedCapKey), std::to_string(*speed_cap));
  if (const auto error = write_batch(context.store, b)) {
    ++stats.storage_errors;
    spdlog::error("command {}: result {} could not be stored: {}",
                  r.command_id().empty() ? "<no id>" : r.command_id(),
                  command_result_name(r.result()), *error);
    if (speed_cap) {
      spdlog::error("command {}: speed cap {} km/h in force but not stored", r.command_id(),
                    *speed_cap);
      r.mutable_mc()->set_limit_in_force(r.mc().limit_in_force() +
                                         " (cap not stored: lost at a restart)");
    }
    answer_unstored(std::move(r), now, journal ? journal_expires : std::nullopt, received);
    return;
  }
  ++stored_count;
  if (observer) observer(r, false);
}

CommandService::Impl::WriteScope::WriteScope(Impl& impl) : impl_(impl), outer_(impl.writing) {
  impl_.writing = true;
  if (!outer_) impl_.write_pending();
}

// What the bus side concluded, oldest first. One at a time: an observer may hand in the next
// command, whose scope must not write these again.
void CommandService::Impl::write_pending() {
  while (!pending.empty()) {
    Pending p = std::move(pending.front());
    pending.erase(pending.begin());
    store_result(std::move(p.result), p.at, p.journal_expires, p.received, p.speed_cap);
  }
}

void CommandService::Impl::emit_unstored(const v1::CommandResult& r) {
  unstored_out.push_back({r.command_id(), r.SerializeAsString()});
}

// The store refused: publish directly (stored = false) and keep the journal write for later.
void CommandService::Impl::answer_unstored(v1::CommandResult r, Micros now,
                                           std::optional<Micros> journal_expires,
                                           std::optional<Micros> received) {
  r.set_stored(false);
  ++stats.results_unstored;
  emit_unstored(r);
  if (journal_expires) {
    if (unjournaled.size() >= config.max_unjournaled && !unjournaled.contains(r.command_id())) {
      const auto oldest =
          std::min_element(unjournaled.begin(), unjournaled.end(),
                           [](const auto& a, const auto& b) { return a.second.at < b.second.at; });
      spdlog::error("command {}: given up journaling its result (more than {} waiting)",
                    oldest->first, config.max_unjournaled);
      unjournaled.erase(oldest);
      ++stats.unjournaled_dropped;
    }
    unjournaled[r.command_id()] = {r, journal_expires, received.value_or(now), now, false, true};
  }
  if (observer) observer(r, false);
}

void CommandService::Impl::unstored_handed(std::string_view command_id, bool handed) {
  if (!handed) {
    ++stats.unstored_not_published;
    spdlog::warn("command {}: unstored result could not be handed to the uplink{}",
                 command_id.empty() ? "<no id>" : command_id,
                 unjournaled.contains(command_id) ? "; it goes out once the store accepts it" : "");
  }
  const auto it = unjournaled.find(command_id);
  if (it == unjournaled.end() || !it->second.awaiting) return;  // a re-sent answer
  it->second.awaiting = false;
  it->second.published = handed;
}

// Writes the journal rows the store refused earlier, oldest first, until one fails. An entry
// whose direct publish was not reported yet waits: whether the outbox must send it is unknown.
void CommandService::Impl::retry_unjournaled(Micros now) {
  if (now < next_journal_retry) return;
  next_journal_retry = now + kJournalRetryInterval;
  std::vector<std::string> order;
  for (const auto& [id, u] : unjournaled) {
    if (!u.awaiting) order.push_back(id);
  }
  std::stable_sort(order.begin(), order.end(), [&](const auto& a, const auto& b) {
    return unjournaled.at(a).at < unjournaled.at(b).at;
  });
  for (const auto& id : order) {
    Unjournaled& u = unjournaled.at(id);
    v1::CommandResult stored = u.result;
    stored.set_stored(true);
    storage::Batch b;
    b.now_us = now.count();
    std::optional<storage::Bytes> uplink;
    // Already published directly: the row only. Otherwise the outbox sends it now.
    if (!u.published) uplink = to_bytes(stored.SerializeAsString());
    b.command_results.push_back({row_of(stored, u.at), std::move(uplink)});
    b.commands.push_back(journal_of(stored, u.received, *u.journal_expires));
    if (const auto error = write_batch(context.store, b)) {
      spdlog::debug("command: journal retry failed, {} result(s) waiting: {}", unjournaled.size(),
                    *error);
      return;
    }
    spdlog::info("command {}: result journaled after the store recovered", id);
    const bool queued = !u.published;
    unjournaled.erase(id);
    if (queued) ++stored_count;
  }
}

void CommandService::Impl::count(const v1::CommandResult& r) {
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

bool CommandService::Impl::take_token(Micros now) {
  const double per_minute = config.unauthenticated_results_per_minute;
  if (per_minute <= 0) return false;
  if (now > tokens_at) {
    tokens = std::min(per_minute,
                      tokens + per_minute * static_cast<double>((now - tokens_at).count()) / 60e6);
    tokens_at = now;
  }
  if (tokens < 1) return false;
  tokens -= 1;
  return true;
}

Disposition CommandService::Impl::reject(const Rejection& rej, Micros now,
                                         std::optional<Micros> expires, bool always_answer) {
  v1::CommandResult r;
  r.set_command_id(rej.command_id);
  r.set_command_sha256(rej.command_sha256);
  r.set_payload_sha256(rej.payload_sha256);
  r.set_operator_id(rej.operator_id);
  r.set_result(v1::COMMAND_RESULT_CODE_REJECTED);
  // The detail quotes received strings only through untrusted_excerpt: one safe line.
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
  store_result(std::move(r), now, keep, now);
  return Disposition::kRejected;
}

Disposition CommandService::Impl::duplicate(const storage::CommandJournalRow& entry,
                                            const std::string& sha, Micros now,
                                            const std::string& operator_id) {
  ++stats.duplicates;
  if (entry.state == kExecuting) {
    if (executing(entry.command_id)) {
      spdlog::info("command {}: duplicate delivery while executing; ignored", entry.command_id);
      return Disposition::kDuplicateInProgress;
    }
    // Journaled by an earlier run that did not finish (recover() not called yet).
    finish_interrupted(entry, now, sha, operator_id);
    return Disposition::kDuplicateAnswered;
  }
  if (!take_token(now)) {
    ++stats.results_dropped;
    return Disposition::kDropped;
  }
  // The stored result, queued again (a message without a new row: still one result per id).
  v1::CommandResult r;
  r.set_command_id(entry.command_id);
  r.set_command_sha256(sha);
  r.set_operator_id(operator_id);
  r.set_result(code_from_name(entry.state));
  bool found = false;
  try {
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
  } catch (const std::exception& e) {
    spdlog::error("command {}: reading the stored result failed: {}", entry.command_id, e.what());
  }
  const auto& names = config.decode_options.lock_state_names;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (!r.final_lock_state_name().empty() && names[i] == r.final_lock_state_name()) {
      r.set_final_lock_state(proto_state(static_cast<std::uint8_t>(i)));
    }
  }
  ensure_utf8(r);
  spdlog::info("command {}: duplicate delivery; stored result '{}' queued again", entry.command_id,
               command_result_name(r.result()));
  r.set_stored(true);
  storage::Batch b;
  b.now_us = now.count();
  b.messages.push_back({storage::OutboxKind::kCommandResult,
                        static_cast<int>(storage::OutboxPriority::kCommandResult),
                        to_bytes(r.SerializeAsString())});
  if (const auto error = write_batch(context.store, b)) {
    ++stats.storage_errors;
    spdlog::error("command {}: re-sending the stored result failed: {}", entry.command_id, *error);
    answer_unstored(std::move(r), now, std::nullopt, std::nullopt);  // journaled already
    return Disposition::kDuplicateAnswered;
  }
  ++stored_count;
  if (observer) observer(r, true);
  return Disposition::kDuplicateAnswered;
}

// A redelivery of a command whose answer the store refused: the same answer, published again.
Disposition CommandService::Impl::duplicate_unjournaled(const Unjournaled& u, Micros now) {
  ++stats.duplicates;
  if (!take_token(now)) {
    ++stats.results_dropped;
    return Disposition::kDropped;
  }
  spdlog::info("command {}: duplicate delivery; unstored result '{}' published again",
               u.result.command_id(), command_result_name(u.result.result()));
  emit_unstored(u.result);
  if (observer) observer(u.result, true);
  return Disposition::kDuplicateAnswered;
}

void CommandService::Impl::finish_interrupted(const storage::CommandJournalRow& entry, Micros now,
                                              const std::string& sha,
                                              const std::string& operator_id) {
  v1::CommandResult r;
  r.set_command_id(entry.command_id);
  r.set_operator_id(operator_id);
  r.set_command_sha256(sha.empty() ? entry.command_sha256 : sha);
  r.set_result(v1::COMMAND_RESULT_CODE_TIMEOUT);
  // Lock and MC commands alike: the bus never confirmed it, and it is not sent again.
  r.set_reason(
      "interrupted_by_restart: the gateway stopped before the bus confirmed the command; not "
      "sent again");
  r.set_duration_ms(static_cast<std::uint64_t>(to_ms(now - Micros(entry.received_us))));
  count(r);
  ++stats.recovered;
  spdlog::warn("command {}: {}", entry.command_id, r.reason());
  store_result(std::move(r), now, Micros(entry.expires_at_us), Micros(entry.received_us));
}

}  // namespace fleetgw::command
