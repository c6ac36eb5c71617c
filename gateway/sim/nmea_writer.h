// The simulated bike's GNSS receiver: NMEA 0183 sentences for its position, written to a
// pseudo-terminal that a real gpsd reads like a serial GPS (docs/simulator.md, "Route").
//
// Contract:
//  * Formatting is pure: nmea_fix() gives one GGA and one RMC sentence ("$...*HH\r\n", the
//    checksum the XOR of the characters between '$' and '*'), time and date from `utc` (Unix
//    microseconds), coordinates as ddmm.mmmmm / dddmm.mmmmm with hemisphere letters, rounded
//    once on the whole minutes (59.999999' becomes the next degree, never "60.00000").
//  * NmeaPty creates a pty in raw mode, keeps its slave side open (so writes never fail for
//    want of a reader) and points `link` at the slave (replacing an existing symlink, never a
//    regular file); the destructor removes the link if it still points at this pty. write()
//    never blocks: when the pty is full (no gpsd reading), the sentence is dropped, as on a
//    serial line nobody listens to. Bytes a reader sends back (gpsd probes) are discarded.
#pragma once

#include <filesystem>
#include <string>

#include "gateway/sim/scenario.h"

namespace fleetgw::sim {

struct NmeaFix {
  Micros utc{0};
  GeoPoint position;
  double speed_kmh = 0;
  double course_deg = 0;
  int satellites = 9;
  double hdop = 0.9;
  double altitude_m = 35.0;
};

std::string nmea_checksum(std::string_view body);  // two upper-case hex digits
std::string nmea_sentence(std::string_view body);  // "$" body "*" checksum "\r\n"
// "5231.20000,N" (latitude) / "01324.30000,E" (longitude).
std::string nmea_angle(double deg, bool latitude);
// GGA then RMC for one fix.
std::string nmea_fix(const NmeaFix& fix);

class NmeaPty {
 public:
  explicit NmeaPty(std::filesystem::path link);  // throws std::runtime_error naming the step
  ~NmeaPty();
  NmeaPty(const NmeaPty&) = delete;
  NmeaPty& operator=(const NmeaPty&) = delete;

  // Returns false when the sentence was dropped (pty full or broken).
  bool write(std::string_view text);
  const std::filesystem::path& link() const { return link_; }
  const std::string& slave_path() const { return slave_path_; }

 private:
  std::filesystem::path link_;
  std::string slave_path_;
  int master_ = -1;
  int slave_ = -1;
};

}  // namespace fleetgw::sim
