#include "gateway/sim/sim_bus.h"

#include "gateway/sim/scenario.h"
#include "gateway/sim/sim_transport.h"

namespace fleetgw::sim {

std::unique_ptr<can::PacedTransport> open_sim_bus(asio::io_context& io,
                                                  const config::SimConfig& config,
                                                  motinova::Micros wall_now) {
  Scenario scenario = load_scenario(config.scenario);
  if (config.start_now) scenario.start = wall_now;
  if (config.seed != 0) scenario.seed = static_cast<uint64_t>(config.seed);
  auto t = std::make_unique<SimTransport>(io, std::move(scenario), config.speed);
  if (!config.nmea_pty.empty()) t->serve_nmea(config.nmea_pty);
  t->set_lockstep(config.lockstep);
  return t;
}

}  // namespace fleetgw::sim
