#include "gateway/can/transport.h"

namespace fleetgw::can {

std::string_view link_state_name(LinkState s) {
  switch (s) {
    case LinkState::kUp:
      return "up";
    case LinkState::kErrorWarning:
      return "error_warning";
    case LinkState::kErrorPassive:
      return "error_passive";
    case LinkState::kBusOff:
      return "bus_off";
    case LinkState::kDown:
      return "down";
  }
  return "?";
}

}  // namespace fleetgw::can
