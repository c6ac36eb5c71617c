// GpsdClient: a connection to gpsd through libgps (Debian's libgps-dev), read without blocking.
//
// Contract:
//  * The first connect() loads libgps (dlopen: a process with [gnss] off never maps it or the
//    libraries it needs); a missing library is an error text like any other.
//  * connect() opens the TCP connection and enables JSON watching; it returns an error text
//    instead of throwing (gpsd missing is an expected field condition, not a bug). The connect
//    itself blocks: point it at a local gpsd (the deployed setup), not at a remote host.
//  * fd() is the socket to watch for readability (the owner's event loop); after it becomes
//    readable, read_available() consumes every complete report already received and returns
//    them, in order. It never waits for more.
//  * A report is a fix (mode 2D/3D with latitude and longitude: a Position stamped with the
//    `now` given) or a "no fix" (mode reported, but below 2D). Everything received from gpsd is
//    untrusted: non-finite or out-of-range coordinates are dropped as "no fix". A fix carries
//    the horizontal error of the latest TPV that had one (eph, else epx and epy) if it came
//    within 2 s (gpsd sends it with some of a cycle's TPVs only), and the hdop and satellites of
//    the latest SKY report, if one came (position.h: never one derived from the other). Its
//    heading is the latest TPV track reported with a speed of at least 1 km/h within 2 s, the
//    same way (gpsd sends the track with the RMC's TPV, not the GGA's); a TPV with a lower speed
//    clears it (issue 27).
//  * A read error or EOF closes the connection (connected() turns false) and is reported once
//    through the return value; the owner reconnects on its own schedule.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gateway/gnss/position.h"

namespace fleetgw::gnss {

struct GnssReport {
  std::optional<Fix> fix;  // nullopt: the receiver reports no fix
};

class GpsdClient {
 public:
  // `library_name`: the libgps to load at the first connect() (tests name a missing one).
  GpsdClient(std::string host, std::string port, std::string library_name = FLEETGW_LIBGPS_SONAME);
  ~GpsdClient();
  GpsdClient(const GpsdClient&) = delete;
  GpsdClient& operator=(const GpsdClient&) = delete;

  // Empty on success, else why (e.g. "connect to localhost:2947: Connection refused").
  std::string connect();
  void close();
  bool connected() const { return data_ != nullptr; }
  int fd() const;
  std::string endpoint() const { return host_ + ":" + port_; }

  enum class ReadStatus { kOk, kClosed };
  ReadStatus read_available(Micros now, std::vector<GnssReport>& out);

 private:
  struct Library;  // libgps's functions, loaded by the first connect()
  struct Data;     // libgps's gps_data_t, kept out of this header
  struct DataDeleter {
    void operator()(Data* d) const;
  };
  std::string load_library();  // empty on success, else why
  std::string host_;
  std::string port_;
  std::string library_name_;
  std::unique_ptr<Library> library_;  // before data_: destroyed after it
  std::unique_ptr<Data, DataDeleter> data_;
  std::optional<double> hdop_;                // SKY reports arrive apart from the TPV fixes
  std::optional<double> horizontal_error_m_;  // the latest TPV eph, at horizontal_error_at_
  Micros horizontal_error_at_{0};
  std::optional<double> heading_deg_;  // the latest TPV track while moving, at heading_at_
  Micros heading_at_{0};
  int satellites_ = 0;
};

}  // namespace fleetgw::gnss
