// The simulated bike as the bus of `fleetgw run` (can.transport = "sim"): the opener that the
// fleetgw binary and the tests hand to the service (runtime::ServiceOptions::open_sim), so the
// runtime reaches the simulator only through can::PacedTransport and never links it.
//
// Contract: open_sim_bus(io, config, wall_now) loads config.scenario (throws naming the file on a
// bad scenario), applies seed (0 keeps the scenario's) and start_now (the timeline starts at
// `wall_now`, microseconds since the epoch), and returns a SimTransport at config.speed, serving
// NMEA on config.nmea_pty when it is set, lock-step when config.lockstep. Nothing runs until the
// transport is started.
#pragma once

#include <memory>

#include <asio/io_context.hpp>

#include "gateway/can/paced_transport.h"
#include "gateway/config/config.h"

namespace fleetgw::sim {

std::unique_ptr<can::PacedTransport> open_sim_bus(asio::io_context& io,
                                                  const config::SimConfig& config,
                                                  motinova::Micros wall_now);

}  // namespace fleetgw::sim
