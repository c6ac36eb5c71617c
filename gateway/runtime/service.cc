#include "gateway/runtime/service.h"

#include <spdlog/spdlog.h>

#include <asio/io_context.hpp>
#include <asio/signal_set.hpp>
#include <asio/steady_timer.hpp>
#include <iostream>

#include "gateway/can/replay_transport.h"
#include "gateway/can/socketcan_transport.h"
#include "gateway/can/udp_transport.h"
#include "gateway/command/command_service.h"
#include "gateway/node/transport_sender.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/status_provider.h"
#include "gateway/runtime/store_outbox.h"
#include "gateway/sim/scenario.h"
#include "gateway/sim/sim_transport.h"
#include "gateway/status/notifier.h"
#include "gateway/status/status_server.h"
#include "gateway/uplink/uplink.h"
#include "storage/store.h"

namespace fleetgw::runtime {
namespace {

Micros system_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
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
    sim::Scenario scenario = sim::load_scenario(c.sim.scenario);
    if (c.sim.start_now) scenario.start = system_now();
    if (c.sim.seed != 0) scenario.seed = static_cast<uint64_t>(c.sim.seed);
    auto t = std::make_unique<sim::SimTransport>(io, std::move(scenario), c.sim.speed);
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

uplink::UplinkConfig make_uplink_config(const config::Config& c) {
  uplink::UplinkConfig u;
  u.broker_uri = c.mqtt.uri;
  u.vehicle_id = c.vehicle.id;
  u.topic_prefix = c.mqtt.topic_prefix;
  u.firmware_version = FLEETGW_VERSION;
  const bool tls = c.mqtt.uri.rfind("ssl://", 0) == 0 || c.mqtt.uri.rfind("mqtts://", 0) == 0;
  if (tls) {
    uplink::TlsConfig t;
    t.ca_file = c.mqtt.ca_file;
    t.cert_file = c.mqtt.cert_file;
    t.key_file = c.mqtt.key_file;
    t.verify_server_name = c.mqtt.verify_server;
    u.tls = t;
  }
  u.username = c.mqtt.username;
  u.password = c.mqtt.password;
  u.keep_alive = std::chrono::seconds(c.mqtt.keepalive_s);
  u.tcp_nodelay = c.mqtt.tcp_nodelay;
  u.reconnect_min = std::chrono::milliseconds(c.mqtt.reconnect_min_ms);
  u.reconnect_max = std::chrono::milliseconds(c.mqtt.reconnect_max_ms);
  u.max_in_flight = static_cast<std::size_t>(c.mqtt.max_inflight);
  u.live_telemetry_qos = c.mqtt.telemetry_qos;
  u.telemetry_batch_max_samples = static_cast<std::size_t>(c.mqtt.batch_max_samples);
  u.telemetry_batch_max_delay = std::chrono::milliseconds(c.mqtt.batch_max_ms);
  return u;
}

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

  std::optional<storage::Store> store;
  try {
    store.emplace(make_store_options(config));
  } catch (const std::exception& e) {
    spdlog::critical("cannot open the store {}: {}", config.storage.path, e.what());
    return 1;
  }
  if (store->moved_aside_path()) {
    spdlog::error("the previous database was unreadable and was moved to {}; started a fresh one",
                  *store->moved_aside_path());
  }

  // The transport's timeline (see the header).
  Micros last_frame_ts{0};
  auto now = [&]() -> Micros {
    // The simulator's frames carry its virtual time; once they flow they are the clock, so a
    // machine too slow for the acceleration sees a consistent (if slower) timeline.
    if (bus.sim) return last_frame_ts.count() > 0 ? last_frame_ts : bus.sim->virtual_now();
    if (bus.replay) return last_frame_ts;
    return system_now();
  };

  const auto wall_start = std::chrono::steady_clock::now();
  Micros first_ts{-1};
  bool stopping = false;
  asio::steady_timer tick_timer(io);
  asio::steady_timer live_timer(io);
  asio::steady_timer stop_timer(io);
  asio::steady_timer uplink_timer(io);
  asio::signal_set signals(io, SIGINT, SIGTERM);
  // systemd integration: READY once bus and store are open, watchdog pings from this loop.
  status::Notifier notifier = status::Notifier::from_environment();
  std::optional<status::LoopWatchdog> watchdog;
  std::optional<status::StatusServer> status_server;

  auto stop = [&](const char* why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("stopping: {}", why);
    notifier.stopping();
    if (watchdog) watchdog->stop();
    if (status_server) status_server->stop();
    bus.transport->stop();
    tick_timer.cancel();
    live_timer.cancel();
    uplink_timer.cancel();
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
    // Wake up when the core next has work, at most every 50 ms (replays tick from frames).
    tick_timer.expires_after(std::chrono::milliseconds(50));
    tick_timer.async_wait([&](const std::error_code& ec) {
      // A handler already queued when stop() cancelled the timer runs without an error.
      if (ec || stopping) return;
      // A replay's clock only moves with its frames; the other timelines move by themselves.
      if (!bus.replay) {
        const Micros t = now();
        if (t >= core.next_event()) core.tick(t);
      }
      // Measured on the frames actually delivered: a paced simulator's clock can run ahead of
      // a slow machine, the traffic cannot.
      if (options.bus_duration && first_ts.count() >= 0 &&
          last_frame_ts - first_ts >= *options.bus_duration) {
        stop("bus duration reached");
        return;
      }
      arm_tick();
    });
  };
  std::ostream& live_out = options.live_out ? *options.live_out : std::cout;
  std::function<void()> arm_live = [&] {
    live_timer.expires_after(std::chrono::seconds(1));
    live_timer.async_wait([&](const std::error_code& ec) {
      if (ec || stopping) return;
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
  Recorder recorder(config, *store, start);

  // Remote lock commands: verified, journaled in the store, executed through the node.
  std::unique_ptr<command::CommandService> commands;
  try {
    commands = std::make_unique<command::CommandService>(
        command::make_command_service_config(config),
        command::CommandContext{core.node(), *store, &recorder.trackers(),
                                command::default_clock_synchronised, system_now});
  } catch (const std::exception& e) {
    spdlog::critical("invalid [command] configuration: {}", e.what());
    return 1;
  }
  if (const auto n = commands->recover(start)) {
    spdlog::warn("{} command(s) interrupted by the previous stop finished as timeout", n);
  }
  struct CommandFeed final : MessageListener {
    command::CommandService& svc;
    explicit CommandFeed(command::CommandService& s) : svc(s) {}
    void on_message(const motinova::DecodedMessage& m, Micros t) override { svc.on_message(m, t); }
    void tick(Micros t) override { svc.tick(t); }
  } command_feed(*commands);
  core.add_listener(command_feed);

  // The uplink drains the store's outbox; Paho's threads only wake the loop up.
  StoreOutbox outbox(*store);
  std::unique_ptr<uplink::Uplink> up;
  std::function<void()> poll_uplink = [] {};
  if (config.mqtt.enabled) {
    try {
      up = std::make_unique<uplink::Uplink>(make_uplink_config(config), outbox);
    } catch (const std::exception& e) {
      spdlog::critical("invalid [mqtt] configuration: {}", e.what());
      return 1;
    }
    // The network lives in real time even when the bus is simulated or replayed faster:
    // back-off and keep-alive must not run at 400x.
    poll_uplink = [&] {
      if (stopping) return;
      up->poll(system_now());
    };
    up->set_wakeup([&io, &poll_uplink] { asio::post(io, [&poll_uplink] { poll_uplink(); }); });
    up->set_command_handler([&](std::string_view payload) {
      const auto d = commands->on_payload(payload, now());
      spdlog::info("command received: {}", command::disposition_name(d));
      recorder.flush(now());  // results leave at once, not at the next flush
    });
    recorder.set_after_flush([&] { poll_uplink(); });
  }
  core.add_listener(recorder);
  if (options.on_core) options.on_core(core);
  core.start(start);
  spdlog::info("fleetgw {} running on {} ({} transport)", FLEETGW_VERSION, bus.transport->name(),
               config.can.transport);
  arm_tick();
  if (options.live_view) arm_live();
  std::function<void()> arm_uplink = [&] {
    uplink_timer.expires_after(std::chrono::milliseconds(200));
    uplink_timer.async_wait([&](const std::error_code& ec) {
      if (ec || stopping) return;
      poll_uplink();
      arm_uplink();
    });
  };
  if (up) {
    up->start(system_now());
    arm_uplink();
  }
  if (const auto timeout = status::watchdog_timeout_from_environment()) {
    watchdog.emplace(io, notifier, *timeout);
    watchdog->start();
  }
  if (!config.status.socket.empty()) {
    try {
      const std::filesystem::path socket(config.status.socket);
      if (socket.has_parent_path()) std::filesystem::create_directories(socket.parent_path());
      status_server.emplace(io, socket, [&] {
        return make_status_json(
            StatusInputs{config, core, *bus.transport, *store, up.get(), start, now()});
      });
    } catch (const std::exception& e) {
      spdlog::warn("status socket {} disabled: {}", config.status.socket, e.what());
    }
  }
  notifier.ready(std::string(config.can.transport) + " on " + std::string(bus.transport->name()));
  io.run();
  recorder.flush(bus.replay ? last_frame_ts : now());
  if (up) {
    // Give the last records a moment to leave, then publish the retained offline status.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (std::chrono::steady_clock::now() < deadline && outbox.stats().depth > 0 &&
           up->state() == uplink::LinkState::kConnected) {
      up->poll(system_now());
      up->wait_for_events(std::chrono::milliseconds(50));
    }
    up->stop(system_now());
    const auto s = up->stats();
    spdlog::info("uplink: {} records acked in {} messages, {} reconnects, {} still queued",
                 s.acked_records, s.acked_messages, s.reconnects, outbox.stats().depth);
  }

  const auto& stats = core.bus_stats();
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const double virt =
      first_ts.count() < 0 ? 0.0 : static_cast<double>((last_frame_ts - first_ts).count()) / 1e6;
  spdlog::info(
      "stopped: {} CAN frames, {} messages, {} frame errors, {:.1f} s of bus time in "
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
