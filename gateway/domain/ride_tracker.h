// RideTracker: turns MC/BMS traffic into ride records.
//
// Contract:
//  * Clock-free: fed decoded messages (on_message) and tick(now); `now` never goes backwards.
//    The caller also feeds the frames the gateway itself transmits (0x760 LOCK/UNLOCK/SHUTDOWN),
//    since the bus does not echo them.
//  * A ride starts when the vehicle is not locked (no 0x760 LOCK since the last UNLOCK, and not
//    all locks locked by a lock transition) and the MC reports a speed above moving_speed_kmh,
//    or its trip counters advance (a 0.1 km step, or counter_start_s of trip time). It ends on a
//    0x760 LOCK, on a transition after which every lock heard reports "locked", on a system
//    SHUTDOWN (0x760, 0x730, 0x720), or after standing still for stationary_end -- then at the
//    moment it stopped, with the energy and SOC of that moment. An MC silent for stationary_end
//    ends it at the last MC message.
//  * Every open ride is upserted (no uplink payload) at its start and every checkpoint_interval;
//    the closed ride is upserted once more with its RideRecord payload. Ride ids are the start
//    time ("<prefix>20240601T080012.345678Z"): unique per vehicle and stable across restarts.
//  * restore() resumes the open ride of a previous run from Store::open_rides(): marked partial
//    ("gateway_restart"), it keeps accumulating; the odometer steps made while the gateway was
//    down are counted (distance covers the whole ride). Energy, moving and assist time cannot
//    be known for the gap: the gap's time is booked as assist "unknown" so assist times still
//    sum to the duration. A ride is never split and never lost. Its positions (start, GNSS
//    distance, simplified track: the row's v6 columns) resume from the checkpoint too.
//  * Every upsert carries the ride's positions so far (start/end fix, GNSS distance, the
//    simplified track as storage::track_text()), the same as the RideRecord payload's; all
//    empty while no fix was received during the ride.
//  * Distance: the plausible positive steps of the best MC counter seen throughout the ride
//    (mc_odometer odo 0.1 km > mc_status trip 0.1 km > mc_status odo 1 km), else integrated
//    speed; the integrated distance is always reported next to it as a cross-check. Energy:
//    ∫ V·I of the BMS while its status is fresh, else of the MC (sample and hold, no bridging
//    of gaps longer than sample_gap). A ride whose MC goes silent for mc_offline_timeout is
//    marked partial ("bus_lost").
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>

#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/payloads.h"
#include "gateway/domain/ride_track.h"
#include "gateway/domain/signals.h"
#include "motinova/codec.h"
#include "storage/records.h"

namespace fleetgw::domain {

class RideTracker {
 public:
  RideTracker(RideConfig config, DomainSink& sink);

  // Resumes the newest open ride of a previous run; older ones (there should be none) are
  // closed as partial at their last checkpoint.
  void restore(std::span<const storage::RideRow> open_rides, Micros now);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // A fault was raised (fed by the fault tracker through the facade).
  void on_fault_raised(Micros now);
  // A current GNSS fix (the facade passes every one): the open ride's track (RideTrack).
  void on_position(const gnss::Fix& position) {
    if (open_) open_->track.add(position);
  }

  bool riding() const { return open_.has_value(); }
  // The open ride as it would be checkpointed now (nullopt when parked).
  std::optional<storage::RideRow> current(Micros now) const;
  uint64_t rides_closed() const { return rides_closed_; }

 private:
  // A monotonic MC counter: sums the plausible positive steps between readings.
  struct Counter {
    std::optional<double> last;
    Micros at{0};
    double total = 0;  // running sum of accepted steps
  };
  // Everything accumulated over one ride; a value copy is kept at each stop so a ride ended by
  // the stationary timeout ends at the stop, not 10 minutes later.
  struct Open {
    storage::RideRow rec;
    std::string partial_reason;
    Micros attributed_until{0};     // assist/moving time booked up to here
    double base_distance_km = 0;    // restored from a checkpoint
    double base_integrated_km = 0;  // idem
    std::array<double, 3> base{};   // counter totals at the start (or resume)
    std::array<bool, 3> valid{};    // counter known at the start and heard since
    std::optional<double> latest_soc;
    RideTrack track;  // positions since the start (or the resume after a restart)
  };

  void start(Micros now);
  void close(Micros end, bool at_stop);
  void checkpoint(Micros now);
  void attribute(Open& o, Micros until) const;
  void feed_counter(std::size_t i, double value, double resolution_km, Micros now);
  void integrate_power(const std::optional<Micros>& last_at,
                       const std::optional<std::pair<double, double>>& last, Micros now);
  void on_mc_status(const motinova::DecodedMessage& msg, Micros now);
  void on_bms_status(const motinova::DecodedMessage& msg, Micros now);
  void on_lock_status(const motinova::DecodedMessage& msg, Micros now);
  void check_counter_start(Micros now);
  std::optional<double> soc(Micros now) const;
  std::optional<double> odometer() const;
  storage::RideRow snapshot(const Open& o, Micros until) const;
  void emit(const storage::RideRow& rec, const Open& o, bool with_payload);

  RideConfig config_;
  DomainSink& sink_;

  // Vehicle state, tracked whether or not a ride is open.
  bool vehicle_locked_ = false;
  bool all_locks_locked_ = false;  // set by a transition, cleared when a lock leaves "locked"
  std::array<std::optional<int64_t>, 5> lock_states_{};
  std::optional<Micros> last_mc_;
  std::optional<double> speed_;
  std::optional<Micros> speed_at_;
  std::string assist_ = "unknown";
  std::map<std::string, unsigned> assist_raw_;
  std::optional<Reading> bms_soc_, mc_soc_, coarse_odo_;
  std::optional<Micros> bms_at_;
  // Energy integration: last (power, current) per source and when.
  std::optional<std::pair<double, double>> bms_pw_, mc_pw_;
  std::optional<Micros> bms_pw_at_, mc_pw_at_;
  Micros energy_until_{0};
  // Counters: 0 = mc_odometer odo (0.1 km), 1 = mc_status trip (0.1 km), 2 = mc_status odo (1 km).
  std::array<Counter, 3> counters_{};
  std::optional<double> fine_odo_;
  // Trip-counter start detection while parked: baseline trip time and when it was taken.
  std::optional<Reading> trip_time_base_;
  std::optional<double> trip_time_;
  std::array<Reading, 2> parked_base_{};  // counter totals when the bike last parked

  Micros no_start_until_{0};  // after a SHUTDOWN
  std::optional<Open> open_;
  std::optional<Open> at_stop_;  // copy taken when the bike last came to a standstill
  bool moving_ = false;
  Micros last_motion_{0};
  Micros next_checkpoint_{0};
  std::optional<Micros> resumed_at_;  // set by restore(); cleared by the first MC message
  uint64_t rides_closed_ = 0;
};

}  // namespace fleetgw::domain
