#include "gateway/can/transport.h"

namespace fleetgw::can {

std::string_view controller_state_name(ControllerState s) {
  switch (s) {
    case ControllerState::kUp:
      return "up";
    case ControllerState::kErrorWarning:
      return "error_warning";
    case ControllerState::kErrorPassive:
      return "error_passive";
    case ControllerState::kBusOff:
      return "bus_off";
    case ControllerState::kDown:
      return "down";
  }
  return "?";
}

}  // namespace fleetgw::can
