#include "gateway/runtime/service.h"

#include <spdlog/spdlog.h>

#include <asio/io_context.hpp>
#include <asio/signal_set.hpp>
#include <csignal>

#include "gateway/can/replay_transport.h"
#include "gateway/can/socketcan_transport.h"
#include "gateway/can/udp_transport.h"
#include "gateway/runtime/clock_units.h"
#include "gateway/runtime/pipeline.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/status_provider.h"
#include "gateway/status/notifier.h"
#include "gateway/status/status_server.h"
#include "storage/store.h"

namespace fleetgw::runtime {
namespace {

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

BusTransport make_bus(asio::io_context& io, const config::Config& c, const SimBusOpener& open_sim,
                      Env& env) {
  BusTransport bus;
  if (c.can.transport == "sim") {
    if (!open_sim) throw std::runtime_error("this program was built without the simulator");
    auto t = open_sim(io, c.sim, env.wall_now());
    bus.sim = t.get();
    bus.sim_speed = c.sim.speed;
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
    bus.transport = std::make_unique<can::UdpTransport>(io, o, env);
  } else {
    can::SocketCanOptions o;
    o.interface = c.can.interface;
    bus.transport = std::make_unique<can::SocketCanTransport>(io, o, env);
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
  u.qos = c.mqtt.qos;
  u.live_telemetry_qos = c.mqtt.telemetry_qos;
  u.live_telemetry_max_age = std::chrono::milliseconds(c.mqtt.live_telemetry_max_age_ms);
  u.telemetry_batch_max_samples = static_cast<std::size_t>(c.mqtt.batch_max_samples);
  u.telemetry_batch_max_delay = std::chrono::milliseconds(c.mqtt.batch_max_ms);
  u.protocol = c.mqtt.protocol == "3.1.1" ? uplink::MqttProtocol::kV311 : uplink::MqttProtocol::kV5;
  u.session_expiry = std::chrono::seconds(c.mqtt.session_expiry_s);
  u.will_delay = std::chrono::seconds(c.mqtt.will_delay_s);
  return u;
}

int run_service(const config::Config& config, const ServiceOptions& options,
                ServiceReport* report) {
  asio::io_context io;
  // The one environment of the process (env/env.h): every part built below reads time, starts
  // threads and writes files through it.
  Env& env = Env::system();
  // First: from here a SIGTERM is a clean stop (delivered once the loop runs), never the default
  // action halfway through opening the bus, the store or a simulator's pty link.
  asio::signal_set signals(io, SIGINT, SIGTERM);
  // A peer that resets its socket must be an error on that socket, never the end of the bike's
  // service: libgps's gps_close() writes to gpsd's socket after gpsd reset it (EPIPE), and a
  // plain write() there raises SIGPIPE, whose default action kills the process. Ignored for the
  // whole process, as every network daemon does; asio, Paho and libpq already expect it.
  struct sigaction ignore_pipe {};
  ignore_pipe.sa_handler = SIG_IGN;
  ::sigaction(SIGPIPE, &ignore_pipe, nullptr);
  BusTransport bus;
  try {
    bus = make_bus(io, config, options.open_sim, env);
  } catch (const std::exception& e) {
    spdlog::critical("cannot open the CAN bus ({}): {}", config.can.transport, e.what());
    return 1;
  }
  std::optional<storage::Store> store;
  try {
    // A missing directory is a configuration error (a typo, an unmounted card), never created.
    const std::filesystem::path db(config.storage.path);
    if (db.has_parent_path() && !std::filesystem::is_directory(db.parent_path())) {
      spdlog::critical("storage.path: directory {} does not exist", db.parent_path().string());
      return 1;
    }
    storage::StoreOptions store_options = make_store_options(config);
    store_options.env = &env;
    store.emplace(std::move(store_options));
  } catch (const std::exception& e) {
    spdlog::critical("cannot open the store {}: {}", config.storage.path, e.what());
    return 1;
  }
  if (store->moved_aside_path()) {
    spdlog::error("the previous database was unreadable and was moved to {}; started a fresh one",
                  *store->moved_aside_path());
  }

  const auto wall_start = env.steady_now();
  // systemd integration: READY once bus and store are open, watchdog pings from this loop.
  status::Notifier notifier = status::Notifier::from_environment();
  std::optional<status::LoopWatchdog> watchdog;
  std::optional<status::StatusServer> status_server;

  PipelineOptions po;
  po.env = &env;
  po.duration = options.duration;
  po.bus_duration = options.bus_duration;
  po.live_view = options.live_view;
  po.live_out = options.live_out;
  po.on_core = options.on_core;
  po.stop_when = options.stop_when;
  po.on_stop = [&](const char*) {
    notifier.stopping();
    if (watchdog) watchdog->stop();
    if (status_server) status_server->stop();
    signals.cancel();
  };
  const std::string transport_name = config.can.transport;
  std::optional<Pipeline> pipeline;
  try {
    pipeline.emplace(io, config, std::move(bus), *store, std::move(po));
  } catch (const PipelineError& e) {
    spdlog::critical("{}", e.what());
    return 1;
  }
  signals.async_wait([&](const std::error_code& ec, int signo) {
    if (!ec) pipeline->stop(signo == SIGINT ? "SIGINT" : "SIGTERM");
  });
  spdlog::info("fleetgw {} running on {} ({} transport)", FLEETGW_VERSION,
               pipeline->transport().name(), transport_name);
  if (const auto timeout = status::watchdog_timeout_from_environment()) {
    watchdog.emplace(io, notifier, *timeout, env);
    watchdog->start();
  }
  if (!config.status.socket.empty()) {
    try {
      const std::filesystem::path socket(config.status.socket);
      if (socket.has_parent_path()) std::filesystem::create_directories(socket.parent_path());
      status_server.emplace(io, socket, [&] { return pipeline->status_document(); });
    } catch (const std::exception& e) {
      spdlog::warn("status socket {} disabled: {}", config.status.socket, e.what());
    }
  }
  notifier.ready(transport_name + " on " + std::string(pipeline->transport().name()));
  io.run();
  pipeline->finish();

  GatewayCore& core = pipeline->core();
  const auto& stats = core.bus_stats();
  const double wall = std::chrono::duration<double>(env.steady_now() - wall_start).count();
  const double virt = pipeline->bus_seconds();
  const auto& c = pipeline->counters();
  spdlog::info(
      "stopped: {} CAN frames, {} messages, {} frame errors, {:.1f} s of bus time in "
      "{:.2f} s ({} timer wake-ups, {} settles, {} uplink polls)",
      stats.can_frames, core.stats().messages, stats.total_errors(), virt, wall, c.timer_wakeups,
      c.settles, c.uplink_polls);
  if (report) {
    report->can_frames = stats.can_frames;
    report->messages = core.stats().messages;
    report->frame_errors = stats.total_errors();
    report->virtual_seconds = virt;
    report->wall_seconds = wall;
    report->last_live_line = core.live().line();
    report->counters = c;
  }
  return 0;
}

}  // namespace fleetgw::runtime
