#include "gateway/runtime/stages.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/node/messages.h"

namespace fleetgw::runtime {

std::optional<EngineTime> CoreStage::next_deadline() const {
  // A replay's clock only moves with its frames, and on_can_frame() ticks the core by itself.
  if (clock_.replay()) return std::nullopt;
  // The node's own deadlines are exact; the listeners (trackers, commands) need the timer only
  // on a silent bus, at their idle cadence: flowing frames tick them (on_can_frame).
  return clock_.to_engine(std::min(core_.node_deadline(), core_.idle_deadline()));
}

StageRun CoreStage::run(EngineTime) {
  // The node's deadlines are on the bus timeline (accelerated for the simulator): the core acts
  // in every timer turn, with the bus's own clock deciding what is due.
  if (!engine_.timer_turn() || clock_.replay()) return {};
  timer_turn_ = true;
  Micros t = clock_.now();
  if (sim_) {
    // The core acts on its deadline with every frame due by now delivered (batching).
    sim_->flush();
    if (engine_.stopped()) return {};
    t = clock_.latest();
  }
  if (t >= core_.next_event()) core_.tick(t);
  return {};
}

std::optional<EngineTime> RecorderStage::next_deadline() const {
  if (recorder_.urgent()) return engine_.now();
  return recorder_.flush_deadline();
}

StageRun RecorderStage::run(EngineTime now) {
  const auto due = recorder_.flush_deadline();
  const bool urgent = recorder_.urgent();
  // The deadline is "at the latest": pending telemetry rides along with a wake-up that happens
  // anyway (the node's schedule) instead of costing one of its own. Not in a replay, whose group
  // commits should stay large.
  const bool piggyback = engine_.timer_turn() && !clock_.replay();
  if (!urgent && !(due && (piggyback || now >= *due))) return {};
  if (urgent) ++urgent_flushes_;
  const FlushOutcome out = recorder_.flush(clock_.now());
  if (!out.status.ok()) {
    return {.produced = 0,
            .status = Status::error(out.status.code, "write failed, records kept: " +
                                                         recorder_.health().last_error)};
  }
  if (out.records > 0) stored_ = true;
  return {.produced = 0, .status = {}};
}

fleetgw::v1::BusState bus_state(const can::Transport& transport, const BusClock& clock,
                                Micros offline_timeout) {
  switch (transport.health().state) {
    case can::ControllerState::kBusOff:
      return fleetgw::v1::BUS_STATE_BUS_OFF;
    case can::ControllerState::kErrorPassive:
      return fleetgw::v1::BUS_STATE_ERROR_PASSIVE;
    case can::ControllerState::kDown:
      return fleetgw::v1::BUS_STATE_SILENT;
    case can::ControllerState::kUp:
    case can::ControllerState::kErrorWarning:
      break;
  }
  // Frames flowing: heard within the time after which a node counts as offline.
  if (!clock.heard()) return fleetgw::v1::BUS_STATE_SILENT;
  return clock.latest() - clock.last_frame() > offline_timeout ? fleetgw::v1::BUS_STATE_SILENT
                                                               : fleetgw::v1::BUS_STATE_ACTIVE;
}

std::optional<EngineTime> UplinkStage::next_deadline() const {
  if (publish_due_ || !direct.empty()) return engine_.now();
  auto at = uplink_.next_deadline();
  if (outbox_) {
    if (const auto retry = outbox_->next_retry(); retry && (!at || *retry < *at)) at = retry;
  }
  return at;
}

StageRun UplinkStage::run(EngineTime now) {
  if (outbox_) outbox_->retry_deletes();  // a no-op unless a retry is due
  for (auto& d : std::exchange(direct, {})) {
    const bool ok = uplink_.publish_direct(d.kind, std::move(d.payload), engine_.env().wall_now());
    direct_handed.emplace_back(std::move(d.tag), ok);
  }
  const auto poll_at = uplink_.next_deadline();
  const bool woken = woken_.exchange(false);
  if (!publish_due_ && !woken && !(poll_at && now >= *poll_at)) {
    return {.produced = direct_handed.size(), .status = {}};
  }
  publish_due_ = false;
  ++polls_;
  uplink_.poll(engine_.env().wall_now());
  // Handled by the routes after poll() returned: poll is never re-entered.
  auto append = [](auto& to, auto&& from) {
    if (to.empty()) {
      to = std::move(from);
    } else {
      for (auto& x : from) to.push_back(std::move(x));
    }
  };
  append(commands, uplink_.take_commands());
  append(busy, uplink_.take_busy_commands());
  append(bundles, uplink_.take_zone_bundles());
  return {.produced = commands.size() + busy.size() + bundles.size() + direct_handed.size(),
          .status = {}};
}

StageRun GnssStage::run(EngineTime) {
  // A loss is reported first, so the first reconnect waits the back-off; otherwise a due
  // attempt is made now (the engine does not run this stage before its retry time).
  std::optional<std::string> error = feed_.take_loss();
  if (!error && feed_.needs_connect()) error = feed_.connect();
  Status status = error ? Status::error(StatusCode::kUnavailable, std::move(*error)) : Status{};
  if (engine_.timer_turn()) feed_.on_timer();
  if (!feed_.changed()) return {.produced = 0, .status = std::move(status)};
  feed_.take_changed();
  const auto wall = feed_.wall_now();
  update = Update{wall, feed_.state().current(wall)};
  // The policy: the IoT node's own fault word carries "position unknown" (0x0004).
  const bool now_fault = !update->position;
  if (fault_ != now_fault) {
    if (now_fault) {
      spdlog::warn("gnss: position unknown ({}): IoT fault bit 0x0004 set",
                   feed_.state().reason(wall));
    } else if (fault_) {
      spdlog::info("gnss: fix acquired: IoT fault bit 0x0004 cleared");
    }
    fault_ = now_fault;
    fault = now_fault;
  }
  return {.produced = 1, .status = std::move(status)};
}

StageRun DeviceInfoStage::run(EngineTime) {
  if (!reporter_.due()) return {};
  if (auto payload = reporter_.take(registry_)) {
    record = storage::UplinkMessage{storage::OutboxKind::kInfo,
                                    static_cast<int>(storage::OutboxPriority::kPack),
                                    storage::Bytes(payload->begin(), payload->end())};
    return {.produced = 1, .status = {}};
  }
  return {};
}

StageRun TimerStage::run(EngineTime now) {
  if (!at_ || now < *at_) return {};
  due_ = true;
  if (period_.count() > 0) {
    at_ = now + period_;
  } else {
    at_.reset();
  }
  return {.produced = 1, .status = {}};
}

}  // namespace fleetgw::runtime
