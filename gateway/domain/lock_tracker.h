// LockTracker: one lock event per lock-state change of every lock node (LOCK 1..5, 0x7n0/0x1010),
// intermediate states (unlocking, locking) and failures included.
//
// Contract:
//  * Clock-free: on_message(msg, now), tick(now). The first state heard from a lock is its
//    baseline, not an event (the gateway cannot know what it was before).
//  * Each event: lock node, kind (LockConfig::lock_kinds, U21; "lockN" when not configured),
//    old/new state names (U19 table), cause. Cause: the one announced with expect_cause() for
//    that lock (the command service: "command:<id>"), else "vehicle_lock"/"vehicle_unlock" after
//    a 0x760 LOCK/UNLOCK, else "local". An announced cause covers the lock's changes until it
//    reaches a final state (locked, unlocked, lock/unlock failed) or cause_window has passed;
//    an explicit cause is never overridden by a later vehicle LOCK/UNLOCK.
//  * set_observer(): called with each event as it is appended to the sink (and its new U19 state
//    code), inside on_message(): the observer must only take note (the geofence's no-parking
//    report of a lock made on the bike), never call back into the trackers.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>

#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/gnss/position.h"
#include "motinova/codec.h"

namespace fleetgw::domain {

class LockTracker {
 public:
  LockTracker(LockConfig config, DomainSink& sink);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // The current GNSS fix (nullopt: unknown); lock events carry the latest one given.
  void set_position(const std::optional<gnss::Fix>& position) { position_ = position; }

  using Observer = std::function<void(const storage::LockEventRow& event, int new_raw)>;
  void set_observer(Observer observer) { observer_ = std::move(observer); }

  // Announces why the next state changes of `lock` (a lock node; kBroadcast = every lock) happen.
  void expect_cause(motinova::Node lock, std::string cause, Micros now);

  // Last state code heard from lock index 0..4 (nullopt: never heard).
  std::optional<int> state(std::size_t index) const { return locks_.at(index).state; }
  const std::string& kind(std::size_t index) const { return config_.lock_kinds.at(index); }

 private:
  struct Cause {
    std::string text;
    Micros until{0};
    bool explicit_ = false;
  };
  struct Lock {
    std::optional<int> state;
    std::optional<Cause> cause;
  };

  void set_cause(std::size_t index, std::string cause, Micros now, bool explicit_cause);
  std::string state_name(int raw) const;

  LockConfig config_;
  DomainSink& sink_;
  std::array<Lock, 5> locks_{};
  std::optional<gnss::Fix> position_;
  Observer observer_;
};

}  // namespace fleetgw::domain
