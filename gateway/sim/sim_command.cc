#include "gateway/sim/sim_command.h"

#include <charconv>
#include <csignal>
#include <fstream>
#include <iostream>
#include <optional>
#include <vector>

#include <spdlog/spdlog.h>
#include <asio/signal_set.hpp>
#include <asio/steady_timer.hpp>

#include "gateway/can/socketcan_transport.h"
#include "gateway/can/timed_work_timer.h"
#include "gateway/can/udp_transport.h"
#include "gateway/sim/bus_log_writer.h"
#include "gateway/sim/scenario.h"
#include "gateway/sim/sim_gnss.h"
#include "gateway/sim/sim_transport.h"

namespace fleetgw::sim {
namespace {

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t pos = s.find(sep, start);
    parts.push_back(s.substr(start, pos == std::string_view::npos ? pos : pos - start));
    if (pos == std::string_view::npos) return parts;
    start = pos + 1;
  }
}

uint16_t parse_port(std::string_view text, std::string_view spec) {
  unsigned value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value == 0 || value > 65535) {
    throw std::invalid_argument("--bus " + std::string(spec) + ": \"" + std::string(text) +
                                "\" is not a port number (1..65535)");
  }
  return static_cast<uint16_t>(value);
}

}  // namespace

std::unique_ptr<can::Transport> make_bus_transport(asio::io_context& io, std::string_view spec) {
  const std::vector<std::string_view> parts = split(spec, ':');
  if (parts[0] == "udp" && (parts.size() == 3 || parts.size() == 5)) {
    can::UdpOptions o;
    if (parts.size() == 3) {
      o.local_port = parse_port(parts[1], spec);
      o.remote_port = parse_port(parts[2], spec);
    } else {
      o.local_address = std::string(parts[1]);
      o.local_port = parse_port(parts[2], spec);
      o.remote_address = std::string(parts[3]);
      o.remote_port = parse_port(parts[4], spec);
    }
    return std::make_unique<can::UdpTransport>(io, o);
  }
  if (parts[0] == "socketcan" && parts.size() == 2 && !parts[1].empty()) {
    can::SocketCanOptions o;
    o.interface = std::string(parts[1]);
    return std::make_unique<can::SocketCanTransport>(io, o);
  }
  throw std::invalid_argument("--bus \"" + std::string(spec) +
                              "\": expected udp:<local port>:<remote port>, "
                              "udp:<addr>:<port>:<addr>:<port> or socketcan:<interface>");
}

int run_sim(const SimCliOptions& options) {
  Scenario scenario;
  try {
    scenario = load_scenario(options.scenario);
  } catch (const ScenarioError& e) {
    std::cerr << "fleetgw sim: " << e.what() << '\n';
    return 2;
  }
  if (options.seed) scenario.seed = *options.seed;
  if (options.duration_s) {
    if (!(*options.duration_s > 0)) {
      std::cerr << "fleetgw sim: --duration must be positive\n";
      return 2;
    }
    scenario.duration = Micros(static_cast<int64_t>(*options.duration_s * 1e6));
  }
  const Micros duration = scenario.effective_duration();
  if (!options.nmea_pty.empty()) {
    // Checked before anything is opened: a pty without a position to serve is a usage error.
    if (scenario.route.size() < 2) {
      std::cerr << "fleetgw sim: --nmea-pty " << options.nmea_pty.string() << ": scenario "
                << options.scenario.string()
                << " has no [[route]], so the simulated bike has no position to serve\n";
      return 2;
    }
    if (!options.record.empty()) {
      std::cerr << "fleetgw sim: --nmea-pty serves the route in real time; it cannot be combined "
                   "with --record\n";
      return 2;
    }
  }

  if (!options.record.empty()) {
    std::ofstream out(options.record, std::ios::binary | std::ios::trunc);
    if (!out) {
      std::cerr << "fleetgw sim: cannot write " << options.record << '\n';
      return 1;
    }
    const std::size_t lines = record_scenario(scenario, duration, out);
    if (!out) {
      std::cerr << "fleetgw sim: write error on " << options.record << '\n';
      return 1;
    }
    spdlog::info("sim: wrote {} frames ({} s of scenario '{}') to {}", lines,
                 duration.count() / 1'000'000, scenario.name, options.record.string());
    return 0;
  }
  if (!(options.speed > 0) || options.speed > 1e6) {
    std::cerr << "fleetgw sim: --speed must be in (0, 1e6]\n";
    return 2;
  }

  asio::io_context io;
  std::unique_ptr<can::Transport> transport;
  try {
    transport = options.transport_factory ? options.transport_factory(io, options.bus)
                                          : make_bus_transport(io, options.bus);
  } catch (const std::invalid_argument& e) {
    std::cerr << "fleetgw sim: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "fleetgw sim: cannot open bus: " << e.what() << '\n';
    return 1;
  }
  if (!transport) {
    std::cerr << "fleetgw sim: no transport for --bus " << options.bus << '\n';
    return 2;
  }

  Bike bike(scenario);
  // Installed before the pty link exists: a SIGTERM that arrives once the link is visible must
  // reach the handler (which removes the link), not the default action (which would leave it).
  asio::signal_set signals(io, SIGINT, SIGTERM);
  // Declared before the driver, whose hook calls it: destroyed after it, and the link with it.
  std::unique_ptr<SimGnss> gnss;
  if (!options.nmea_pty.empty()) {
    try {
      gnss = std::make_unique<SimGnss>(bike, options.nmea_pty);
    } catch (const std::exception& e) {
      // SimGnss names the configuration key of `fleetgw run`; here the option is the name.
      std::string_view why = e.what();
      if (why.starts_with("sim.nmea_pty: ")) why.remove_prefix(14);
      std::cerr << "fleetgw sim: --nmea-pty " << options.nmea_pty.string() << ": " << why << '\n';
      return 1;
    }
  }
  RealtimeDriver driver(io, bike, options.speed);
  // The same wiring as SimTransport::serve_nmea: one fix per second of bus time.
  if (gnss) driver.set_on_advanced([&](Micros t) { gnss->on_bus_time(t); });
  const Micros end = scenario.start + duration;
  uint64_t tx_failures = 0;
  asio::steady_timer end_check(io);

  // A SocketCAN bus re-opens and retries a full driver queue when polled: without the
  // gateway's engine here, a timer of the transport's own kind does it.
  std::optional<can::TimedWorkTimer> timed;
  if (auto* work = transport->timed_work()) timed.emplace(io, *work).start();
  auto shutdown = [&] {
    driver.stop();
    if (timed) timed->stop();
    transport->stop();
    signals.cancel();
    end_check.cancel();
  };
  transport->start([&](const motinova::CanFrame& frame, Micros) { driver.receive(frame); },
                   [](const can::BusHealth& h) {
                     spdlog::info("sim: bus {} ({})", can::controller_state_name(h.state),
                                  h.detail);
                   });
  if (gnss) gnss->on_bus_time(bike.current_time());  // where the bike stands at the start
  bool ended = false;
  driver.start([&](const motinova::CanFrame& frame, Micros ts) {
    // Nothing stamped past the end goes on the bus, however late the check below comes (it
    // looks every 100 ms of real time, minutes of bus time at a high speed).
    if (ts > end) {
      if (!ended) shutdown();
      ended = true;
      return;
    }
    if (!transport->send(frame)) ++tx_failures;
  });
  signals.async_wait([&](const std::error_code& ec, int) {
    if (!ec) shutdown();
  });
  // Checks the virtual end every 100 ms of real time (the bike keeps its own schedule).
  std::function<void()> check = [&] {
    end_check.expires_after(std::chrono::milliseconds(100));
    end_check.async_wait([&](const std::error_code& ec) {
      if (ec) return;
      if (driver.virtual_now() >= end) {
        shutdown();
      } else {
        check();
      }
    });
  };
  check();
  spdlog::info("sim: scenario '{}' (seed {}) on {} at x{} for {} s of virtual time", scenario.name,
               scenario.seed, transport->name(), options.speed, duration.count() / 1'000'000);
  if (gnss) {
    spdlog::info("sim: serving the route as NMEA on {} -> {}", options.nmea_pty.string(),
                 gnss->pty().slave_path());
  }
  io.run();

  const BikeStats& s = bike.stats();
  spdlog::info("sim: done: {} messages / {} CAN frames sent, {} frames heard, {} tx failures",
               s.messages_sent, s.can_frames_sent, s.external_frames, tx_failures);
  if (gnss) {
    spdlog::info("sim: {} NMEA fixes written, {} dropped (the pty was full: nobody read it)",
                 gnss->fixes_written(), gnss->fixes_dropped());
  }
  return 0;
}

}  // namespace fleetgw::sim
