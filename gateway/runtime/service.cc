#include "gateway/runtime/service.h"

#include <spdlog/spdlog.h>

#include <asio/io_context.hpp>
#include <asio/signal_set.hpp>
#include <asio/steady_timer.hpp>
#include <iostream>

#include "gateway/can/replay_transport.h"
#include "gateway/can/socketcan_transport.h"
#include "gateway/can/udp_transport.h"
#include "gateway/node/transport_sender.h"
#include "gateway/sim/scenario.h"
#include "gateway/sim/sim_transport.h"

namespace fleetgw::runtime {
namespace {

Micros system_now() {
  return std::chrono::duration_cast<Micros>(
      std::chrono::system_clock::now().time_since_epoch());
}

// "127.0.0.1:20000" -> address, port; throws naming the key.
std::pair<std::string, uint16_t> endpoint(const std::string& text, const char* key) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) {
    throw std::invalid_argument(std::string("can.") + key + ": expected address:port, got \"" +
                                text + "\"");
  }
  const int port = std::stoi(text.substr(colon + 1));
  if (port <= 0 || port > 65535) {
    throw std::invalid_argument(std::string("can.") + key + ": port out of range");
  }
  return {text.substr(0, colon), static_cast<uint16_t>(port)};
}

struct Bus {
  std::unique_ptr<can::Transport> transport;
  sim::SimTransport* sim = nullptr;
  can::ReplayTransport* replay = nullptr;
};

Bus make_bus(asio::io_context& io, const config::Config& c) {
  Bus bus;
  if (c.can.transport == "sim") {
    auto t = std::make_unique<sim::SimTransport>(io, sim::load_scenario(c.sim.scenario),
                                                 c.sim.speed);
    bus.sim = t.get();
    bus.transport = std::move(t);
  } else if (c.can.transport == "replay") {
    can::ReplayOptions o;
    o.pace = c.can.replay_speed > 0 ? can::ReplayOptions::Pace::kRecorded
                                    : can::ReplayOptions::Pace::kAsFastAsPossible;
    if (c.can.replay_speed > 0) o.speed = c.can.replay_speed;
    auto t = std::make_unique<can::ReplayTransport>(io, c.can.replay_file, o);
    bus.replay = t.get();
    bus.transport = std::move(t);
  } else if (c.can.transport == "udp") {
    can::UdpOptions o;
    std::tie(o.local_address, o.local_port) = endpoint(c.can.udp_local, "udp_local");
    std::tie(o.remote_address, o.remote_port) = endpoint(c.can.udp_remote, "udp_remote");
    bus.transport = std::make_unique<can::UdpTransport>(io, o);
  } else {
    can::SocketCanOptions o;
    o.interface = c.can.interface;
    bus.transport = std::make_unique<can::SocketCanTransport>(io, o);
  }
  return bus;
}

}  // namespace

int run_service(const config::Config& config, const ServiceOptions& options,
                ServiceReport* report) {
  asio::io_context io;
  Bus bus;
  try {
    bus = make_bus(io, config);
  } catch (const std::exception& e) {
    spdlog::critical("cannot open the CAN bus ({}): {}", config.can.transport, e.what());
    return 1;
  }
  node::TransportSender sender(*bus.transport, config.protocol.crc_order);
  node::NodeHooks hooks;
  hooks.on_peer_shutdown = [](motinova::Node initiator, Micros) {
    spdlog::info("{} broadcast SHUTDOWN: state saved, answering READY",
                 motinova::node_name(initiator));
  };
  hooks.acc_off = [](const node::ShutdownOutcome&) { spdlog::info("shutdown complete: ACC off"); };
  GatewayCore core(config, sender, hooks);
  if (options.on_core) options.on_core(core);

  // The transport's timeline (see the header).
  Micros last_frame_ts{0};
  auto now = [&]() -> Micros {
    if (bus.sim) return bus.sim->virtual_now();
    if (bus.replay) return last_frame_ts;
    return system_now();
  };

  const auto wall_start = std::chrono::steady_clock::now();
  Micros first_ts{-1};
  bool stopping = false;
  asio::steady_timer tick_timer(io);
  asio::steady_timer live_timer(io);
  asio::steady_timer stop_timer(io);
  asio::signal_set signals(io, SIGINT, SIGTERM);

  auto stop = [&](const char* why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("stopping: {}", why);
    bus.transport->stop();
    tick_timer.cancel();
    live_timer.cancel();
    stop_timer.cancel();
    signals.cancel();
  };
  signals.async_wait([&](const std::error_code& ec, int signo) {
    if (!ec) stop(signo == SIGINT ? "SIGINT" : "SIGTERM");
  });
  if (options.duration) {
    stop_timer.expires_after(*options.duration);
    stop_timer.async_wait([&](const std::error_code& ec) {
      if (!ec) stop("duration reached");
    });
  }
  if (bus.replay) {
    bus.replay->on_end([&](const can::ReplaySummary& s) {
      spdlog::info("replay finished: {} lines, {} frames, {} malformed lines", s.lines, s.frames,
                   s.malformed_lines);
      core.tick(last_frame_ts + core.kTickInterval);
      stop("end of replay");
    });
  }

  std::function<void()> arm_tick = [&] {
    tick_timer.expires_after(std::chrono::milliseconds(20));
    tick_timer.async_wait([&](const std::error_code& ec) {
      if (ec) return;
      // A replay's clock only moves with its frames; the other timelines move by themselves.
      if (!bus.replay) {
        const Micros t = now();
        if (t >= core.next_event()) core.tick(t);
      }
      arm_tick();
    });
  };
  std::ostream& live_out = options.live_out ? *options.live_out : std::cout;
  std::function<void()> arm_live = [&] {
    live_timer.expires_after(std::chrono::seconds(1));
    live_timer.async_wait([&](const std::error_code& ec) {
      if (ec) return;
      live_out << core.live().line() << std::endl;
      arm_live();
    });
  };

  bus.transport->start(
      [&](const motinova::CanFrame& frame, Micros ts) {
        if (first_ts.count() < 0) first_ts = ts;
        last_frame_ts = ts;
        core.on_can_frame(frame, ts);
      },
      [&](const can::BusHealth& h) {
        spdlog::info("bus {}: {}{}{}", bus.transport->name(), can::link_state_name(h.state),
                     h.detail.empty() ? "" : ": ", h.detail);
      });
  const Micros start = bus.replay ? Micros(0) : now();
  core.start(start);
  spdlog::info("fleetgw {} running on {} ({} transport)", FLEETGW_VERSION, bus.transport->name(),
               config.can.transport);
  arm_tick();
  if (options.live_view) arm_live();
  io.run();

  const auto& stats = core.bus_stats();
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const double virt =
      first_ts.count() < 0 ? 0.0 : static_cast<double>((last_frame_ts - first_ts).count()) / 1e6;
  spdlog::info("stopped: {} CAN frames, {} messages, {} frame errors, {:.1f} s of bus time in "
               "{:.2f} s",
               stats.can_frames, core.stats().messages, stats.total_errors(), virt, wall);
  if (report) {
    report->can_frames = stats.can_frames;
    report->messages = core.stats().messages;
    report->frame_errors = stats.total_errors();
    report->virtual_seconds = virt;
    report->wall_seconds = wall;
    report->last_live_line = core.live().line();
  }
  return 0;
}

}  // namespace fleetgw::runtime
