// `fleetgw sim`: runs a scenario as its own process, putting the simulated bike on a real bus
// (the UDP tunnel or a SocketCAN interface such as vcan0) in real time × an acceleration factor,
// or writing it to a candump -L file. The CLI11 wiring lives in gateway/cli/.
//
// Contract: run_sim() returns a process exit code (0 ok, 2 bad scenario/options, 1 runtime
// failure) and reports problems on stderr with the file/line/key or the transport's message;
// it stops after the duration, or on SIGINT/SIGTERM. With nmea_pty, the pty's link exists while
// the bike runs and is removed when run_sim returns.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <asio/io_context.hpp>

#include "gateway/can/transport.h"

namespace fleetgw::sim {

using TransportFactory =
    std::function<std::unique_ptr<can::Transport>(asio::io_context&, std::string_view spec)>;

struct SimCliOptions {
  std::filesystem::path scenario;    // --scenario (TOML)
  double speed = 1.0;                // --speed: acceleration, 1 = real time
  std::optional<uint64_t> seed;      // --seed: overrides [bike] seed
  std::optional<double> duration_s;  // --duration: overrides the scenario's duration
  // --bus: "udp:<local port>:<remote port>" (127.0.0.1),
  //        "udp:<local addr>:<local port>:<remote addr>:<remote port>", or "socketcan:<ifname>".
  std::string bus = "udp:29537:29536";
  std::filesystem::path record;  // --record FILE: write candump -L instead of a bus
  // --nmea-pty PATH: serve the scenario's [[route]] as NMEA on a pty linked at PATH, as
  // `fleetgw run` does with [sim] nmea_pty (SimGnss); a scenario without a route is exit 2.
  std::filesystem::path nmea_pty;
  TransportFactory transport_factory;  // empty = make_bus_transport (tests inject their own)
};

// Builds the transport named by a --bus spec; throws std::invalid_argument for a malformed spec
// and whatever the transport throws when it cannot open.
std::unique_ptr<can::Transport> make_bus_transport(asio::io_context& io, std::string_view spec);

int run_sim(const SimCliOptions& options);

}  // namespace fleetgw::sim
