// TelemetryTracker: downsampled vehicle state.
//
// Contract:
//  * Clock-free: on_message(msg, now) keeps the latest value of every sampled quantity; tick(now)
//    takes a sample every riding_interval while a ride is open (set_riding) and every
//    parked_interval otherwise. Entering a ride samples at once. A change of a discrete value --
//    assist level, any lock's state, BMS charging flag -- adds a sample at the moment of change
//    (the periodic schedule is not shifted by it).
//  * Values older than `stale` are "not measured" (nullopt). Nothing is sampled before the first
//    value is heard.
//  * Current is discharge-positive (the MC's bus current; -BMS current when the MC is not
//    heard), voltage the MC's (else the BMS's); SOC from the BMS, else the MC. Lock states are
//    U19 codes of the first lock whose kind is listed in wheel_lock_kinds / battery_lock_kinds.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/payloads.h"
#include "gateway/domain/signals.h"
#include "motinova/codec.h"

namespace fleetgw::domain {

class TelemetryTracker {
 public:
  TelemetryTracker(TelemetryConfig config, std::array<std::string, 5> lock_kinds, DomainSink& sink);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  void set_riding(bool riding, Micros now);
  // The current GNSS fix (nullopt: unknown); samples carry the latest one given.
  void set_position(const std::optional<gnss::Fix>& position) { position_ = position; }

  uint64_t samples() const { return samples_; }
  Micros next_due() const { return next_due_.value_or(Micros::max()); }

 private:
  struct Discrete {
    std::optional<int> assist;
    std::array<std::optional<int>, 5> locks{};
    std::optional<bool> charging;
    friend bool operator==(const Discrete&, const Discrete&) = default;
  };
  void sample(Micros now);
  Micros interval() const { return riding_ ? config_.riding_interval : config_.parked_interval; }

  TelemetryConfig config_;
  std::array<std::string, 5> lock_kinds_;
  DomainSink& sink_;
  bool riding_ = false;
  bool heard_ = false;
  std::optional<Micros> next_due_;
  Discrete discrete_;

  // mc_status
  std::optional<Reading> speed_, rpm_, power_, mc_v_, mc_i_, cadence_, torque_, assist_, mc_soc_,
      range_, odo_, trip_, pcb_, motor_t_, mcu_;
  // mc_odometer (0.1 km) wins over mc_status's 1 km odometer
  std::optional<Reading> fine_odo_, fine_trip_;
  // bms_status
  std::optional<Reading> bms_v_, bms_i_, bms_soc_, remaining_, full_, pack_t_;
  std::array<std::optional<Reading>, 5> lock_state_{};
  uint64_t samples_ = 0;
  std::optional<gnss::Fix> position_;
};

}  // namespace fleetgw::domain
