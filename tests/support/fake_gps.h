// Test support: a real gpsd fed with NMEA by gpsfake, so the gateway's real libgps client reads
// the positions a test chooses (tests/support/nmea.h writes the sentences).
//
// Contract:
//  * FakeGps writes `nmea` to <dir>/route.nmea and starts gpsfake on `port` in a process group of
//    its own (gpsfake and the gpsd it starts), its output in <dir>/gpsfake.log. gpsfake feeds
//    one sentence every `cycle_s` seconds from the moment it runs, whether or not a client is
//    connected yet: sentences fed before the gateway connected are lost, so a route should
//    begin with a few seconds at its start. `once` feeds the file once (gpsfake -1) instead of
//    in a loop (gpsfake then stays up, silent); `slow` adds gpsfake's serial-line delays (-S).
//  * kill() (and the destructor) ends the whole group with SIGKILL.
//  * have_gpsfake() is false when gpsd or gpsfake is not installed: the tests skip.
#pragma once

#include <signal.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing {

inline bool have_gpsfake() {
  return std::system("command -v gpsfake >/dev/null 2>&1 && command -v gpsd >/dev/null 2>&1") == 0;
}

class FakeGps {
 public:
  struct Options {
    double cycle_s = 0.5;
    bool once = false;
    bool slow = true;
  };

  FakeGps(const TempDir& dir, std::uint16_t port, const std::string& nmea, Options options)
      : nmea_file_(dir.path() / "route.nmea") {
    std::ofstream(nmea_file_) << nmea;
    std::vector<std::string> argv = {
        "setsid", "gpsfake",           "-q", "-c", std::to_string(options.cycle_s),
        "-P",     std::to_string(port)};
    if (options.once) argv.push_back("-1");
    if (options.slow) argv.push_back("-S");
    argv.push_back(nmea_file_.string());
    process_.emplace(argv, dir.path() / "gpsfake.log");
  }
  ~FakeGps() { kill(); }
  FakeGps(const FakeGps&) = delete;
  FakeGps& operator=(const FakeGps&) = delete;

  void kill() {
    if (!process_) return;
    ::kill(-process_->pid(), SIGKILL);  // the whole group: gpsfake and its gpsd
    process_->kill();
    process_.reset();
  }

 private:
  std::filesystem::path nmea_file_;
  std::optional<ChildProcess> process_;
};

}  // namespace fleetgw::testing
