#include "gateway/sim/bus_log_writer.h"

#include <ostream>

#include "gateway/can/candump.h"

namespace fleetgw::sim {

std::size_t record_scenario(const Scenario& scenario, Micros duration, std::ostream& out,
                            std::string_view interface) {
  Bike bike(scenario);
  std::size_t lines = 0;
  const Bike::Emit emit = [&](const motinova::CanFrame& frame) {
    out << can::candump::format_line(bike.current_time(), interface, frame) << '\n';
    ++lines;
  };
  bike.advance_to(scenario.start + duration, emit);
  out.flush();
  return lines;
}

VirtualBus::Participant candump_writer(std::ostream& out, std::string interface) {
  VirtualBus::Participant p;
  p.name = "candump:" + interface;
  p.on_frame = [&out, interface = std::move(interface)](const motinova::CanFrame& frame,
                                                        Micros ts) {
    out << can::candump::format_line(ts, interface, frame) << '\n';
  };
  return p;
}

}  // namespace fleetgw::sim
