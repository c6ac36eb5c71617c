// AlarmTracker: the operator alarms of a rental fleet, decided from decoded bus traffic.
//
// Contract:
//  * Clock-free and single-threaded like the other trackers: on_message(msg, now) for every
//    decoded message heard or transmitted by the gateway (0x760 LOCK/UNLOCK/SHUTDOWN), tick(now)
//    at least every 200 ms; `now` never goes backwards. expect_command(lock, now) is called by
//    the command service (through DomainTrackers::expect_lock_command) before it drives a lock.
//  * Every transition is one AlarmRecord with its fleetgw.v1.Alarm payload appended to the sink
//    (stored at outbox priority 0). Each alarm is raised ONCE per episode and cleared once.
//  * UNAUTHORISED_MOVEMENT: while the vehicle is locked (0x760 LOCK since the last UNLOCK) or a
//    lock of a frame kind reports "locked", MC wheel speed > movement_speed_kmh or motor rpm >
//    movement_rpm is evidence. Raised when evidence lasts movement_debounce (first to latest
//    evidence sample, with no sample without evidence in between); cleared after movement_clear
//    without evidence. moving_while_locked() is true from the first evidence sample on.
//  * LOCK_FORCED: a lock going from locked/locking to unlocking/unlocked with no command for it
//    in the last command_window (expect_command, the IOT's LOCK/UNLOCK write to that lock, or a
//    0x760 LOCK/UNLOCK); cleared when it reports locked again.
//  * LOCK_TAMPER: a lock's fault word with any bit set; cleared when the word is clear again.
//  * LOW_BATTERY: BMS SOC at or below a threshold, once per threshold (only the lowest one when
//    several are crossed at once); cleared when SOC is back at threshold + hysteresis.
//  * BATTERY_REMOVED: BMS heard before, silent for battery_silent while parked (locked, no
//    movement evidence) and not after a system SHUTDOWN; cleared when the BMS talks again.
//  * BATTERY_SWAPPED (one-shot: raised only): the BMS model info reports a serial different
//    from the last known one AFTER the battery lock (a lock of kind "battery") opened, or first
//    thing after a restart (restore_bms_serial(): the lock could not be watched while the gateway
//    was off), or on a bike where no battery lock was ever heard. A different serial without any
//    of these is adopted silently (no lock opened: not a swap the operator must act on). The
//    alarm waits for the first BMS status after the new serial (at most kSwapStatusWait) so its
//    SOH and cycles are the new pack's. Every change of the known serial is appended to the
//    sink's meta (kBmsSerialMetaKey), so the store keeps the last known serial across restarts.
//  * active() (an alarm other than low battery is raised) and moving_while_locked() drive the
//    telemetry's riding rate (DomainTrackers).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/domain/alarm_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/signals.h"
#include "motinova/codec.h"
#include "storage/records.h"

namespace fleetgw::domain {

class AlarmTracker {
 public:
  AlarmTracker(AlarmConfig config, DomainSink& sink);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // The gateway is about to drive `lock` (kBroadcast: every lock): its next changes are commanded.
  void expect_command(motinova::Node lock, Micros now);
  // Call once, before the first message, with the serial stored by a previous run (the store's
  // meta kBmsSerialMetaKey); an empty string is ignored.
  void restore_bms_serial(std::string serial);

  static constexpr std::string_view kBmsSerialMetaKey = "domain.last_bms_serial";
  // How long a detected swap waits for the new pack's BMS status (SOH, cycles).
  static constexpr Micros kSwapStatusWait{5'000'000};

  // The vehicle counts as locked: 0x760 LOCK since the last UNLOCK, or a frame-kind lock locked.
  bool locked() const;
  bool moving_while_locked() const { return evidence_since_.has_value() || movement_.active; }
  bool active() const;
  // Kinds of the alarms raised and not cleared ("lock_forced", "low_battery"...), each once, in
  // a fixed order (the retained vehicle state lists them). battery_swapped is one-shot: never.
  std::vector<std::string_view> active_kinds() const;
  uint64_t raised_total() const { return raised_total_; }

 private:
  struct Episode {
    bool active = false;
    Micros first{0};
  };
  struct Lock {
    std::optional<int> state;
    Micros commanded_until{0};
    Episode forced;
    Episode tamper;
  };

  void on_mc_status(const motinova::DecodedMessage& msg, Micros now);
  void on_lock_status(std::size_t index, int state, Micros now);
  void on_lock_faults(std::size_t index, uint32_t bits, Micros now);
  void on_soc(double soc, Micros now);
  void on_bms_serial(std::string serial, Micros now);
  void on_battery_lock(int state);
  void raise_swap(Micros now);
  void remember_serial(std::string serial);
  storage::AlarmRow record(std::string_view kind, storage::AlarmTransition t, Micros now,
                              Micros first) const;
  void emit(storage::AlarmRow rec);

  AlarmConfig config_;
  DomainSink& sink_;
  bool vehicle_locked_ = false;
  bool after_shutdown_ = false;
  std::array<Lock, 5> locks_{};
  // Movement.
  std::optional<Reading> speed_, rpm_;
  std::optional<Micros> evidence_since_;
  Micros last_evidence_{0};
  double max_speed_kmh_ = 0;
  Episode movement_;
  // Battery.
  std::optional<Reading> soc_, soh_, cycles_;
  std::optional<Micros> bms_heard_;
  Episode removed_;
  std::vector<bool> low_fired_;    // per threshold (config order): crossed, not re-armed
  std::vector<bool> low_emitted_;  // per threshold: a raised record was sent for it
  std::string bms_serial_;
  // Battery swap: armed (with why) by the battery lock opening or a restart; pending while the
  // alarm waits for the new pack's status.
  struct PendingSwap {
    std::string old_serial, new_serial, why;
    Micros at{0};
  };
  std::optional<std::string> swap_armed_by_;
  std::optional<PendingSwap> pending_swap_;
  std::optional<int> battery_lock_state_;
  uint64_t raised_total_ = 0;
};

}  // namespace fleetgw::domain
