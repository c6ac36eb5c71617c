// GnssState: what the gateway currently knows about its position -- pure logic, no I/O, no
// clock of its own (every entry point takes the wall-clock `now`).
//
// Contract:
//  * on_fix() with a 2D/3D fix makes it the current position; on_no_fix() (the receiver
//    reports mode "no fix") and on_source_lost() (gpsd unreachable or gone) make the position
//    unknown AT ONCE: a stale position is never reported as current.
//  * A fix also stops being current `max_age` after it was received (a receiver that falls
//    silent without saying so). next_change() is the wall time at which that happens, so the
//    owner can wake up for it.
//  * fault(now) is true whenever there is no current position -- the IoT node's GNSS fault bit
//    (iot_fault::kGps, 0x0004, spec §3.5.1). Before the first fix it is true as well: a bike
//    that has never had a fix does not know where it is.
//  * reason(now) names why there is no position ("gpsd unreachable", "no fix", "fix stale"), for
//    the log and `fleetgw status`; empty while current.
#pragma once

#include <optional>
#include <string_view>

#include "gateway/gnss/position.h"

namespace fleetgw::gnss {

struct GnssOptions {
  Micros max_age = std::chrono::seconds(3);
};

class GnssState {
 public:
  explicit GnssState(GnssOptions options = {}) : options_(options) {}

  void on_fix(const Fix& fix);  // uses fix.received_at as "now"
  void on_no_fix(Micros now);
  void on_source_lost(Micros now);
  void on_source_connected(Micros now);

  std::optional<Fix> current(Micros now) const;
  bool fault(Micros now) const { return !current(now).has_value(); }
  std::string_view reason(Micros now) const;
  // When the current fix goes stale; nullopt when there is no current fix.
  std::optional<Micros> next_change(Micros now) const;

  // The last fix ever received (even a stale one), e.g. "last seen at" for status.
  const std::optional<Fix>& last_fix() const { return last_; }
  uint64_t fixes() const { return fixes_; }

 private:
  enum class Source { kNeverConnected, kConnected, kLost };
  GnssOptions options_;
  Source source_ = Source::kNeverConnected;
  bool fix_valid_ = false;  // the receiver's latest report was a fix
  std::optional<Fix> last_;
  uint64_t fixes_ = 0;
};

}  // namespace fleetgw::gnss
