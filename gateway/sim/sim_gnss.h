// The simulated bike's GNSS receiver: once per second of bus time, the point of the scenario's
// route at the distance the bike's odometer has covered since the start, as NMEA on a pty that
// a real gpsd reads (gateway/sim/nmea_writer.h). GNSS and odometer therefore agree; a parked
// bike stays put; past the route's end the bike stays at its last waypoint.
//
// Contract: on_bus_time(t) is called by the driver after the bike has run up to bus time t
// (t never decreases); the first call at or after each whole second writes one fix stamped t.
#pragma once

#include <filesystem>
#include <memory>

#include "gateway/sim/bike.h"
#include "gateway/sim/nmea_writer.h"
#include "gateway/sim/route.h"

namespace fleetgw::sim {

class SimGnss {
 public:
  // Throws std::runtime_error when the scenario has no route or the pty cannot be made.
  SimGnss(const Bike& bike, const std::filesystem::path& link);

  void on_bus_time(Micros t);
  uint64_t fixes_written() const { return written_; }
  uint64_t fixes_dropped() const { return dropped_; }
  const NmeaPty& pty() const { return pty_; }

 private:
  const Bike& bike_;
  RouteWalker route_;
  NmeaPty pty_;
  double start_odo_m_;
  Micros next_fix_{0};
  uint64_t written_ = 0;
  uint64_t dropped_ = 0;
};

}  // namespace fleetgw::sim
