// `fleetgw run`: the long-running service. It opens the CAN transport chosen in the
// configuration and the store, hands them to the Pipeline (pipeline.h: the stages and all their
// scheduling on one asio event loop), and adds what belongs to the process: clean shutdown on
// SIGINT/SIGTERM, systemd notification and watchdog, the status socket.
//
// Contract:
//  * run() blocks until a signal, the optional duration, or the end of a replayed log, and
//    returns the process exit status (0 clean, 1 when the transport could not be opened).
//  * Time: the core runs on the transport's timeline — virtual time for the simulator and for
//    replays (so accelerated runs behave exactly like real ones), the system clock otherwise.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>

#include <asio/io_context.hpp>

#include "gateway/can/paced_transport.h"
#include "gateway/config/config.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/pipeline.h"
#include "gateway/uplink/uplink_config.h"

namespace fleetgw::runtime {

// Opens the simulated bike as the bus (can.transport = "sim"): sim::open_sim_bus
// (gateway/sim/sim_bus.h), passed in by whoever links the simulator. `wall_now` is the system
// clock (microseconds since the epoch) for sim.start_now.
using SimBusOpener = std::function<std::unique_ptr<can::PacedTransport>(
    asio::io_context&, const config::SimConfig&, Micros wall_now)>;

struct ServiceOptions {
  std::optional<std::chrono::milliseconds> duration;  // stop after this much real time
  // Stop once this much bus time has passed (simulated or replayed timelines run faster than
  // the wall clock; this makes a run cover the same traffic however fast the machine is).
  std::optional<Micros> bus_duration;
  bool live_view = false;            // print LiveState::line() every second
  std::ostream* live_out = nullptr;  // default std::cout
  // Called once with the core before the loop starts (tests and the demo attach listeners).
  std::function<void(GatewayCore&)> on_core;
  // Checked after the pipeline handled each burst of work: the run stops once it holds.
  std::function<bool()> stop_when;
  // can.transport = "sim" needs it; without it such a run fails to open the bus (exit 1).
  SimBusOpener open_sim;
};

struct ServiceReport {
  uint64_t can_frames = 0;
  uint64_t messages = 0;
  uint64_t frame_errors = 0;
  double virtual_seconds = 0;  // bus time covered
  double wall_seconds = 0;
  std::string last_live_line;
  PipelineCounters counters;  // wake-ups, settles, polls: what the run cost the event loop
};

uplink::UplinkConfig make_uplink_config(const config::Config& config);

int run_service(const config::Config& config, const ServiceOptions& options,
                ServiceReport* report = nullptr);

}  // namespace fleetgw::runtime
