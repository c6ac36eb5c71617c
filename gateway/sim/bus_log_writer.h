// The bus log writer: simulated bus traffic as a candump -L log (the format of
// gateway/can/candump.h), for the bundled sample logs and for replay-versus-simulation equivalence
// tests.
//
// Contract: deterministic (the output depends only on the scenario and the duration); lines are
// in bus order with the virtual timestamps of the scenario timeline, byte-identical to what
// `candump -L` writes, so the replay transport reads them back unchanged.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <string>
#include <string_view>

#include "gateway/sim/scenario.h"
#include "gateway/sim/virtual_bus.h"

namespace fleetgw::sim {

// Runs `scenario` alone on the bus (no gateway answering) from Scenario::start for `duration`
// and writes every CAN frame. Returns the number of lines written.
std::size_t record_scenario(const Scenario& scenario, Micros duration, std::ostream& out,
                            std::string_view interface = "can0");

// A VirtualBus participant that writes every frame it sees (bike and other participants) to
// `out`, which must outlive the bus: records a whole session, gateway frames included.
VirtualBus::Participant candump_writer(std::ostream& out, std::string interface = "can0");

}  // namespace fleetgw::sim
