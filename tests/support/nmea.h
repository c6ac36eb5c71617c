// Test support: NMEA 0183 sentences (GGA + RMC) for a route, so a real gpsd fed by gpsfake
// serves the positions a test chooses.
//
// Contract:
//  * nmea_route(points, start) writes one GGA and one RMC per point, one second apart, starting
//    at `start` (UTC seconds of day), with valid checksums (gpsd drops sentences whose checksum
//    is wrong). Latitudes and longitudes are WGS-84 degrees.
//  * nmea_checksum() is the XOR of the characters between '$' and '*'.
//  * distance_m() is the great-circle (haversine) distance in metres on the same mean Earth
//    radius as gateway/gnss/position.cc, written independently of it, so a test compares the
//    gateway's distances with its own.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace fleetgw::testing {

struct RoutePoint {
  double lat_deg;
  double lon_deg;
};

inline double distance_m(const RoutePoint& a, const RoutePoint& b) {
  constexpr double kEarthRadiusM = 6'371'008.8;
  constexpr double kRad = M_PI / 180.0;
  const double dlat = (b.lat_deg - a.lat_deg) * kRad;
  const double dlon = (b.lon_deg - a.lon_deg) * kRad;
  const double h = std::sin(dlat / 2) * std::sin(dlat / 2) +
                   std::cos(a.lat_deg * kRad) * std::cos(b.lat_deg * kRad) * std::sin(dlon / 2) *
                       std::sin(dlon / 2);
  return 2 * kEarthRadiusM * std::asin(std::sqrt(h));
}

inline std::string nmea_checksum(const std::string& body) {
  unsigned x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char out[3];
  std::snprintf(out, sizeof out, "%02X", x & 0xFFu);
  return out;
}

inline std::string nmea_sentence(const std::string& body) {
  return "$" + body + "*" + nmea_checksum(body) + "\r\n";
}

// "ddmm.mmmmm,N" / "dddmm.mmmmm,E"
inline std::string nmea_angle(double deg, bool latitude) {
  const char hemi = latitude ? (deg < 0 ? 'S' : 'N') : (deg < 0 ? 'W' : 'E');
  deg = std::fabs(deg);
  const int whole = static_cast<int>(deg);
  const double minutes = (deg - whole) * 60.0;
  char out[32];
  std::snprintf(out, sizeof out, latitude ? "%02d%08.5f,%c" : "%03d%08.5f,%c", whole, minutes,
                hemi);
  return out;
}

inline std::string nmea_route(const std::vector<RoutePoint>& points, int start_s = 36000) {
  std::string out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const int t = (start_s + static_cast<int>(i)) % 86400;
    char hms[16];
    std::snprintf(hms, sizeof hms, "%02d%02d%02d.00", t / 3600, t / 60 % 60, t % 60);
    const std::string lat = nmea_angle(points[i].lat_deg, true);
    const std::string lon = nmea_angle(points[i].lon_deg, false);
    out += nmea_sentence("GPGGA," + std::string(hms) + "," + lat + "," + lon +
                         ",1,08,0.9,35.0,M,45.0,M,,");
    out += nmea_sentence("GPRMC," + std::string(hms) + ",A," + lat + "," + lon +
                         ",10.8,0.0,231126,,,A");
  }
  return out;
}

}  // namespace fleetgw::testing
