#include "gateway/geofence/zone_lock_watch.h"

namespace fleetgw::geofence {
namespace {

// U19 lock state codes (spec; the names are configurable, the codes are not).
constexpr int kUnlocked = 1;
constexpr int kLocked = 2;

}  // namespace

bool BikeLockWatch::on_lock_event(std::string_view kind, int new_raw, std::string_view cause) {
  if (new_raw == kUnlocked) {
    judged_ = false;  // ridden again: the next parking is news
    return false;
  }
  if (new_raw != kLocked || cause.starts_with("command:")) return false;
  const bool ride_ending = kind == "frame" || kind == "wheel" || cause == "vehicle_lock";
  if (!ride_ending || judged_) return false;
  judged_ = true;
  return true;
}

}  // namespace fleetgw::geofence
