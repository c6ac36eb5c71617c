// Position: one GNSS fix as the gateway uses it -- a plain value, no I/O.
//
// Contract:
//  * lat_deg/lon_deg are WGS-84 degrees, valid by construction (a Position exists only for a
//    2D or 3D fix); alt_m, hdop and horizontal_error_m are absent when gpsd did not report
//    them, satellites 0.
//  * Two different measures of accuracy, never derived from each other: hdop (unitless
//    geometry) and satellites come only from gpsd's SKY reports; horizontal_error_m (metres)
//    only from its TPV reports (eph, else the hypotenuse of epx and epy). An NMEA receiver
//    sending only GGA and RMC gets TPV reports alone: a horizontal error, no hdop.
//  * fixed_at is the receiver's UTC time of the fix; received_at is when the gateway got it, on
//    the wall clock (microseconds since the Unix epoch). "Current" is judged from received_at
//    (GnssState), never from fixed_at: a receiver with a wrong clock must not make a stale
//    position look fresh.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>

namespace fleetgw::gnss {

using Micros = std::chrono::microseconds;

struct Fix {
  double lat_deg = 0;
  double lon_deg = 0;
  std::optional<double> alt_m;
  std::optional<double> hdop;  // from SKY
  int satellites = 0;          // used in the solution, from SKY; 0 when not reported
  // gpsd's estimate of the horizontal position error (TPV eph), metres. Its confidence is not
  // stated by gpsd; for an NMEA receiver it is GGA's HDOP times gpsd's fixed range error.
  std::optional<double> horizontal_error_m;
  // Course over ground, degrees clockwise from true north in [0, 360) (TPV track; issue 27);
  // absent when gpsd reported none or the fix moved slower than 1 km/h (noise at a standstill).
  std::optional<double> heading_deg;
  bool three_d = false;
  Micros fixed_at{0};
  Micros received_at{0};

  friend bool operator==(const Fix&, const Fix&) = default;
};

// Great-circle distance in metres (haversine on a sphere of the WGS-84 mean radius: within
// 0.5 % of the ellipsoidal distance, far below GNSS noise for a ride).
double distance_m(double lat1_deg, double lon1_deg, double lat2_deg, double lon2_deg);
inline double distance_m(const Fix& a, const Fix& b) {
  return distance_m(a.lat_deg, a.lon_deg, b.lat_deg, b.lon_deg);
}

}  // namespace fleetgw::gnss
