#include "gateway/sim/sim_gnss.h"

#include <stdexcept>

namespace fleetgw::sim {
namespace {

std::vector<GeoPoint> route_of(const Bike& bike) {
  const Scenario& s = bike.scenario();
  if (s.route.size() < 2) {
    throw std::runtime_error("sim.nmea_pty: scenario " + s.source +
                             " has no [[route]], so the simulated bike has no position to serve");
  }
  return s.route;
}

}  // namespace

SimGnss::SimGnss(const Bike& bike, const std::filesystem::path& link)
    : bike_(bike),
      route_(route_of(bike)),
      pty_(link),
      // The odometer at the start of the scenario: the route begins where the bike stands.
      start_odo_m_(bike.scenario().odo_km * 1000.0) {}

void SimGnss::on_bus_time(Micros t) {
  if (t < next_fix_) return;
  constexpr int64_t kSecond = 1'000'000;
  next_fix_ = Micros((t.count() / kSecond + 1) * kSecond);
  const BikeState state = bike_.state();
  const double along = state.odo_m - start_odo_m_;
  NmeaFix fix;
  fix.utc = t;
  fix.position = route_.at(along);
  fix.speed_kmh = along >= route_.length_m() ? 0 : state.speed_kmh;
  fix.course_deg = route_.course_deg(along);
  if (pty_.write(nmea_fix(fix))) {
    ++written_;
  } else {
    ++dropped_;
  }
}

}  // namespace fleetgw::sim
