#include "gateway/can/error_frame.h"

#include <linux/can/error.h>

namespace fleetgw::can {
namespace {

void add(std::string& out, std::string_view what) {
  if (!out.empty()) out += ", ";
  out += what;
}

uint8_t byte_at(std::span<const uint8_t> data, std::size_t i) {
  return i < data.size() ? data[i] : 0;
}

}  // namespace

ErrorFrameInfo interpret_error_frame(uint32_t error_class, std::span<const uint8_t> data) {
  ErrorFrameInfo info;
  std::optional<ControllerState> state;
  // Later, more severe findings overwrite milder ones; see the precedence in the header.
  auto raise = [&state](ControllerState s) {
    auto rank = [](ControllerState x) {
      switch (x) {
        case ControllerState::kUp:
          return 0;
        case ControllerState::kErrorWarning:
          return 1;
        case ControllerState::kErrorPassive:
          return 2;
        case ControllerState::kBusOff:
          return 3;
        case ControllerState::kDown:
          return 4;
      }
      return 0;
    };
    if (!state || rank(s) > rank(*state)) state = s;
  };

  if (error_class & CAN_ERR_RESTARTED) {
    add(info.description, "controller restarted");
    raise(ControllerState::kUp);
  }
  if (error_class & CAN_ERR_CRTL) {
    const uint8_t c = byte_at(data, 1);
    if (c & CAN_ERR_CRTL_ACTIVE) {
      add(info.description, "controller: back to error-active");
      raise(ControllerState::kUp);
    }
    if (c & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
      add(info.description, (c & CAN_ERR_CRTL_TX_WARNING) ? "controller: tx error-warning"
                                                          : "controller: rx error-warning");
      raise(ControllerState::kErrorWarning);
    }
    if (c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
      add(info.description, (c & CAN_ERR_CRTL_TX_PASSIVE) ? "controller: tx error-passive"
                                                          : "controller: rx error-passive");
      raise(ControllerState::kErrorPassive);
    }
    if (c & CAN_ERR_CRTL_RX_OVERFLOW) add(info.description, "controller: rx buffer overflow");
    if (c & CAN_ERR_CRTL_TX_OVERFLOW) add(info.description, "controller: tx buffer overflow");
    if (c == 0) add(info.description, "controller problem (unspecified)");
  }
  if (error_class & CAN_ERR_BUSOFF) {
    add(info.description, "bus-off");
    raise(ControllerState::kBusOff);
  }
  if (error_class & CAN_ERR_TX_TIMEOUT) add(info.description, "tx timeout");
  if (error_class & CAN_ERR_LOSTARB) add(info.description, "lost arbitration");
  if (error_class & CAN_ERR_PROT) add(info.description, "protocol violation");
  if (error_class & CAN_ERR_TRX) add(info.description, "transceiver problem");
  if (error_class & CAN_ERR_ACK) add(info.description, "no ACK on transmission");
  if (error_class & CAN_ERR_BUSERROR) add(info.description, "bus error");
  if (error_class & CAN_ERR_CNT) {
    add(info.description,
        "tec=" + std::to_string(byte_at(data, 6)) + " rec=" + std::to_string(byte_at(data, 7)));
  }
  if (info.description.empty()) info.description = "error frame (unspecified)";
  info.state = state;
  return info;
}

}  // namespace fleetgw::can
