// Interpretation of SocketCAN error frames (<linux/can/error.h>) into fleetgw bus health.
//
// Contract:
//  * interpret_error_frame() is a pure function of the error class bits (can_id without
//    CAN_ERR_FLAG) and the 8 data bytes: it says which ControllerState the frame implies, if any,
//    and gives a one-line human-readable description ("bus-off", "controller: rx error-passive").
//  * State precedence within one frame: bus-off > error-passive > error-warning > back-to-active
//    (restarted or CAN_ERR_CRTL_ACTIVE → kUp). Frames that only report bus errors, lost
//    arbitration or a missing ACK do not change the state.
//  * Shared by the SocketCAN transport, the replay transport (error frames in candump logs) and
//    the UDP tunnel, so the same frame means the same health everywhere.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "gateway/can/transport.h"

namespace fleetgw::can {

// The error classes fleetgw subscribes to on a raw socket (CAN_RAW_ERR_FILTER). Lost
// arbitration is normal operation on a shared bus and is left out.
inline constexpr uint32_t kSubscribedErrorClasses =
    0x001U /*TX_TIMEOUT*/ | 0x004U /*CRTL*/ | 0x008U /*PROT*/ | 0x010U /*TRX*/ | 0x020U /*ACK*/ |
    0x040U /*BUSOFF*/ | 0x080U /*BUSERROR*/ | 0x100U /*RESTARTED*/;

struct ErrorFrameInfo {
  std::optional<ControllerState> state;  // the state this frame moves the link to, if any
  std::string description;
};

ErrorFrameInfo interpret_error_frame(uint32_t error_class, std::span<const uint8_t> data);

}  // namespace fleetgw::can
