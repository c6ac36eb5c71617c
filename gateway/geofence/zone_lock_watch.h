// BikeLockWatch: which lock events heard on the bus are a rider parking the bike -- a lock made
// on the bike (its key, its own LOCK broadcast), not by a remote command, which the command path
// judges before it runs (CommandService::set_lock_guard). The runtime judges the ones this
// selects against the no-parking zones at the current fix (ZoneEngine::parking, report only: the
// lock has already happened) and reports LOCKED_IN_NO_PARKING like a lock command's.
//
// Contract (pure, no clock):
//  * on_lock_event(kind, new_raw, cause) is true when the event is to be judged now:
//      - the lock reached "locked" (U19 state code 2);
//      - the cause (domain::LockTracker's) is not a command ("command:<id>");
//      - the lock ends a ride, as for commands: a frame or wheel lock, or any lock moved by a
//        vehicle LOCK (cause "vehicle_lock");
//      - it is the first such lock of this parking: the other locks of the same vehicle LOCK (a
//        frame and a wheel lock) are not judged again until a lock is unlocked (code 1).
#pragma once

#include <string_view>

namespace fleetgw::geofence {

class BikeLockWatch {
 public:
  bool on_lock_event(std::string_view kind, int new_raw, std::string_view cause);

 private:
  bool judged_ = false;  // a lock of the current parking was judged
};

}  // namespace fleetgw::geofence
