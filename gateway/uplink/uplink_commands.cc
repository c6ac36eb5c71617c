// The command side of the uplink (uplink.h "Commands"): payloads judged on Paho's thread into
// their lanes before anything is queued, the owner's hand-over, and the drop counting.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>

#include "fleetgw/v1/command.pb.h"
#include "gateway/uplink/uplink_impl.h"

namespace fleetgw::uplink {
namespace detail {

std::string_view drop_class_name(CommandDropClass c) {
  switch (c) {
    case CommandDropClass::kOversized:
      return "oversized";
    case CommandDropClass::kUndecodable:
      return "undecodable";
    case CommandDropClass::kUnauthenticated:
      return "unauthenticated";
    case CommandDropClass::kQueueFull:
      return "queue_full";
  }
  return "unknown";
}

// ---- Paho thread ----
// Cheapest checks first: the size (nothing copied), one SignedCommand parse, then the owner's
// signature check; only then is anything copied into the queue, into the payload's own lane.
void triage_command(std::string_view payload, const UplinkConfig& config,
                    const CommandAuthenticator& authenticator, EventQueue& events) {
  if (payload.size() > config.max_command_bytes) {
    events.push(CommandDropped{CommandDropClass::kOversized,
                               "oversized command (" + std::to_string(payload.size()) +
                                   " bytes > " + std::to_string(config.max_command_bytes) + ")",
                               payload.size() >= kTrimAfterBytes});
    return;
  }
  v1::SignedCommand cmd;
  if (!cmd.ParseFromArray(payload.data(), static_cast<int>(payload.size())) ||
      cmd.command().empty()) {
    events.push(CommandDropped{CommandDropClass::kUndecodable,
                               "undecodable command (" + std::to_string(payload.size()) +
                                   " bytes, not a fleetgw.v1.SignedCommand)"});
    return;
  }
  if (!authenticator) {
    if (events.queued_commands() >= config.max_queued_commands) {
      events.push(CommandDropped{CommandDropClass::kQueueFull,
                                 "command queue full (no authenticator: no busy answer)"});
      return;
    }
    events.push(CommandArrived{std::string(payload), true});
    return;
  }
  CommandTriage triage = authenticator(payload);
  if (!triage.authenticated) {
    if (events.queued_unauthenticated() >= kMaxQueuedUnauthenticated) {
      events.push(CommandDropped{CommandDropClass::kUnauthenticated,
                                 "unauthenticated command (no trusted key's valid signature) "
                                 "over its budget"});
      return;
    }
    events.push(CommandArrived{std::string(payload), false});
    return;
  }
  if (events.queued_commands() < config.max_queued_commands) {
    events.push(CommandArrived{std::string(payload), true});
  } else if (events.queued_busy() < kMaxBusyCommands) {
    events.push(CommandBusy{std::move(triage.command_id), std::move(triage.command_sha256)});
  } else {
    // The id was checked by the authenticator: printable ASCII, at most 128 characters.
    events.push(CommandDropped{CommandDropClass::kQueueFull,
                               "command queue full: authenticated command " + triage.command_id +
                                   " dropped without an answer (" +
                                   std::to_string(kMaxBusyCommands) + " busy answers waiting)"});
  }
}

// ---- owner's thread ----
void record_drop(CommandInbox& inbox, UplinkStats& counters, const std::string& topic,
                 std::chrono::microseconds now, const CommandDropped& e) {
  ++counters.commands_dropped;
  switch (e.drop_class) {
    case CommandDropClass::kOversized:
      ++counters.commands_dropped_oversized;
      break;
    case CommandDropClass::kUndecodable:
      ++counters.commands_dropped_undecodable;
      break;
    case CommandDropClass::kUnauthenticated:
      ++counters.commands_dropped_unauthenticated;
      break;
    case CommandDropClass::kQueueFull:
      ++counters.commands_dropped_queue_full;
      break;
  }
  // A flood must not become a log flood: one line per class per kDropLogInterval.
  const auto k = static_cast<std::size_t>(e.drop_class);
  if (inbox.ever_logged[k] && now - inbox.logged_at[k] < kDropLogInterval) {
    ++inbox.suppressed[k];
    return;
  }
  const std::uint64_t since = std::exchange(inbox.suppressed[k], 0);
  inbox.ever_logged[k] = true;
  inbox.logged_at[k] = now;
  const std::string more = since == 0 ? std::string()
                                      : " (and " + std::to_string(since) + " more " +
                                            std::string(drop_class_name(e.drop_class)) +
                                            " drop(s) since the last such line)";
  if (e.drop_class == CommandDropClass::kQueueFull) {
    spdlog::error("uplink: dropped message on {}: {}{}", topic, e.reason, more);
  } else {
    spdlog::warn("uplink: dropped message on {}: {}{}", topic, e.reason, more);
  }
}

}  // namespace detail

void Uplink::Impl::handle(Micros now, detail::CommandArrived& e) {
  if (!e.authenticated) {
    // The second half of the unauthenticated budget: what reaches the owner's thread.
    auto& in = commands;
    if (!in.tokens_started || now > in.tokens_at) {
      const double elapsed_min =
          in.tokens_started ? static_cast<double>((now - in.tokens_at).count()) / 60e6 : 0;
      in.unauthenticated_tokens =
          std::min(detail::kUnauthenticatedBurst,
                   in.unauthenticated_tokens + elapsed_min * detail::kUnauthenticatedPerMinute);
      in.tokens_at = now;
      in.tokens_started = true;
    }
    if (in.unauthenticated_tokens < 1) {
      events.unauthenticated_taken(1);
      detail::record_drop(commands, counters, topics.cmd, now,
                          {detail::CommandDropClass::kUnauthenticated,
                           "unauthenticated command (no trusted key's valid signature) over "
                           "its rate (" +
                               std::to_string(static_cast<int>(detail::kUnauthenticatedPerMinute)) +
                               " per minute)"});
      return;
    }
    in.unauthenticated_tokens -= 1;
    ++counters.commands_unauthenticated;
  }
  ++counters.commands_received;
  commands.waiting.push_back({std::move(e.payload), e.authenticated});
}

void Uplink::Impl::handle(Micros, detail::CommandBusy& e) {
  ++counters.commands_busy;
  commands.busy.push_back({std::move(e.command_id), std::move(e.command_sha256)});
}

// Releases the queue slots of command events that will never be handled (stop()).
void Uplink::Impl::discard_command_events(const std::deque<detail::Event>& leftover) {
  std::size_t authenticated = 0;
  std::size_t unauthenticated = 0;
  for (const auto& w : commands.waiting) ++(w.authenticated ? authenticated : unauthenticated);
  std::size_t busy = commands.busy.size();
  for (const auto& ev : leftover) {
    if (const auto* c = std::get_if<detail::CommandArrived>(&ev)) {
      ++(c->authenticated ? authenticated : unauthenticated);
    }
    if (std::holds_alternative<detail::CommandBusy>(ev)) ++busy;
  }
  events.commands_taken(authenticated);
  events.unauthenticated_taken(unauthenticated);
  events.busy_taken(busy);
  commands.waiting.clear();
  commands.busy.clear();
}

void Uplink::set_command_authenticator(CommandAuthenticator authenticator) {
  impl_->commands.authenticator = std::move(authenticator);
}

std::vector<std::string> Uplink::take_commands() {
  auto waiting = std::exchange(impl_->commands.waiting, {});
  std::vector<std::string> out;
  out.reserve(waiting.size());
  std::size_t unauthenticated = 0;
  for (auto& w : waiting) {
    unauthenticated += w.authenticated ? 0 : 1;
    out.push_back(std::move(w.payload));
  }
  impl_->events.commands_taken(out.size() - unauthenticated);
  impl_->events.unauthenticated_taken(unauthenticated);
  return out;
}

std::vector<BusyCommand> Uplink::take_busy_commands() {
  auto out = std::exchange(impl_->commands.busy, {});
  impl_->events.busy_taken(out.size());
  return out;
}

}  // namespace fleetgw::uplink
