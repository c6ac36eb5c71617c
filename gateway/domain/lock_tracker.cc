#include "gateway/domain/lock_tracker.h"

#include <utility>

#include "gateway/domain/payloads.h"
#include "gateway/domain/signals.h"
#include "motinova/can.h"

namespace fleetgw::domain {
namespace {

// U19 codes at which a lock has finished moving.
bool final_state(int raw) {
  return raw == 1 || raw == 2 || raw == 5 || raw == 6;
}

}  // namespace

LockTracker::LockTracker(LockConfig config, DomainSink& sink)
    : config_(std::move(config)), sink_(sink) {}

void LockTracker::set_cause(std::size_t index, std::string cause, Micros now, bool explicit_cause) {
  Lock& l = locks_.at(index);
  if (!explicit_cause && l.cause && l.cause->explicit_ && now <= l.cause->until) return;
  l.cause = Cause{std::move(cause), now + config_.cause_window, explicit_cause};
}

void LockTracker::expect_cause(motinova::Node lock, std::string cause, Micros now) {
  if (lock == motinova::Node::kBroadcast) {
    for (std::size_t i = 0; i < locks_.size(); ++i) set_cause(i, cause, now, true);
  } else if (motinova::is_lock(lock)) {
    set_cause(static_cast<std::size_t>(motinova::lock_index(lock)), std::move(cause), now, true);
  }
}

std::string LockTracker::state_name(int raw) const {
  if (raw >= 0 && static_cast<std::size_t>(raw) < config_.lock_state_names.size()) {
    return config_.lock_state_names[static_cast<std::size_t>(raw)];
  }
  return "state_" + std::to_string(raw);
}

void LockTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return;
  switch (classify(msg)) {
    case BusEvent::kVehicleLock:
      for (std::size_t i = 0; i < locks_.size(); ++i) set_cause(i, "vehicle_lock", now, false);
      return;
    case BusEvent::kVehicleUnlock:
      for (std::size_t i = 0; i < locks_.size(); ++i) set_cause(i, "vehicle_unlock", now, false);
      return;
    default:
      break;
  }
  const motinova::Node src = msg.desc->source();
  if (msg.desc->name != "lock_status" || !motinova::is_lock(src)) return;
  const auto raw = msg.raw("state");
  if (!raw) return;
  const auto index = static_cast<std::size_t>(motinova::lock_index(src));
  Lock& l = locks_[index];
  const int next = static_cast<int>(*raw);
  const std::optional<int> before = std::exchange(l.state, next);
  if (!before || *before == next) return;

  if (l.cause && now > l.cause->until) l.cause.reset();
  storage::LockEventRow ev;
  ev.ts_us = now.count();
  ev.lock_node = static_cast<int>(src);
  ev.kind = config_.lock_kinds[index].empty() ? std::string(motinova::node_name(src))
                                              : config_.lock_kinds[index];
  ev.old_state = state_name(*before);
  ev.new_state = state_name(next);
  ev.cause = l.cause ? l.cause->text : "local";
  if (final_state(next)) l.cause.reset();
  storage::Bytes payload = lock_payload(ev, *before, next, position_);
  if (observer_) observer_(ev, next);
  sink_.batch().locks.push_back({std::move(ev), std::move(payload)});
}

void LockTracker::tick(Micros now) {
  for (Lock& l : locks_) {
    if (l.cause && now > l.cause->until) l.cause.reset();
  }
}

}  // namespace fleetgw::domain
