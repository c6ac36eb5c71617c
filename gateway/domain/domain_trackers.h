// DomainTrackers: the five trackers behind one entry point and one config struct.
//
// Contract:
//  * Clock-free and single-threaded: on_message(msg, now) for every decoded application frame
//    heard on the bus AND every frame the gateway transmits (0x760 LOCK/UNLOCK/SHUTDOWN drive
//    rides and lock causes; the bus does not echo them), tick(now) at least every 200 ms (the
//    gateway's batch flush is a good place). `now` must not go backwards.
//  * Everything produced is appended to the caller's DomainSink (which must outlive this
//    object); the caller writes its records to the Store (runtime/recorder.cc).
//  * restore() must be called once, before the first message, with Store::open_rides(): an open
//    ride of a previous run is resumed (see RideTracker).
//  * The ride tracker's fault count is fed from the fault tracker's raises; telemetry follows
//    the ride state (riding vs parked sampling), and is sampled at the riding rate as well while
//    an alarm is active or the bike moves while locked (AlarmTracker).
#pragma once

#include <span>
#include <string>
#include <utility>

#include "gateway/domain/alarm_tracker.h"
#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/fault_tracker.h"
#include "gateway/domain/lock_tracker.h"
#include "gateway/domain/pack_tracker.h"
#include "gateway/domain/ride_tracker.h"
#include "gateway/domain/telemetry_tracker.h"
#include "motinova/codec.h"
#include "storage/records.h"

namespace fleetgw::domain {

class DomainTrackers {
 public:
  // Throws std::invalid_argument (DomainConfig::validate) for a nonsensical config.
  DomainTrackers(DomainConfig config, DomainSink& sink);

  void restore(std::span<const storage::RideRow> open_rides, Micros now);
  // The last BMS serial a previous run stored (meta AlarmTracker::kBmsSerialMetaKey), so a
  // battery swapped while the gateway was off is still reported. Before the first message.
  void restore_bms_serial(std::string serial) { alarms_.restore_bms_serial(std::move(serial)); }
  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // The current GNSS fix, or nullopt when the position is unknown (the owner calls this on
  // every change: telemetry samples and lock events carry the latest one).
  void on_position(const std::optional<gnss::Fix>& position) {
    telemetry_.set_position(position);
    locks_.set_position(position);
    if (position) rides_.on_position(*position);
  }

  // For the command service: the next state changes of `lock` (kBroadcast: all) are caused by
  // "command:<id>".
  void expect_lock_command(motinova::Node lock, const std::string& command_id, Micros now) {
    locks_.expect_cause(lock, "command:" + command_id, now);
    alarms_.expect_command(lock, now);
  }

  // Each lock event as it is produced (LockTracker::set_observer).
  void set_lock_observer(LockTracker::Observer observer) {
    locks_.set_observer(std::move(observer));
  }

  const RideTracker& rides() const { return rides_; }
  const FaultTracker& faults() const { return faults_; }
  const PackTracker& packs() const { return packs_; }
  const TelemetryTracker& telemetry() const { return telemetry_; }
  const LockTracker& locks() const { return locks_; }
  const AlarmTracker& alarms() const { return alarms_; }

 private:
  void sync(Micros now);
  // Telemetry at the riding rate during a ride, and while an alarm is active or the bike moves
  // although locked (the moment an operator most needs data).
  bool fast_telemetry() const {
    return rides_.riding() || alarms_.active() || alarms_.moving_while_locked();
  }

  DomainConfig config_;
  RideTracker rides_;
  FaultTracker faults_;
  PackTracker packs_;
  TelemetryTracker telemetry_;
  LockTracker locks_;
  AlarmTracker alarms_;
  uint64_t faults_seen_ = 0;
};

}  // namespace fleetgw::domain
