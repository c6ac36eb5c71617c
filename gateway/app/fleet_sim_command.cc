// `fleetgw fleet-sim` (fleet_sim_command.h): Paho clients around SimVehicle.
#include "gateway/app/fleet_sim_command.h"

#include <mqtt/async_client.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <csignal>
#include <deque>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>
#include <vector>

#include "gateway/app/fleet_sim_model.h"
#include "gateway/uplink/mqtt_connection.h"

namespace fleetgw::app {
namespace {

using namespace std::chrono_literals;

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string random_store_id(std::mt19937_64& rng) {
  // Version-4 UUID layout, like the gateway's storage.store_id.
  const std::uint64_t a = rng(), b = rng();
  char buf[40];
  std::snprintf(buf, sizeof buf, "%08x-%04x-4%03x-%04x-%012llx", static_cast<unsigned>(a >> 32),
                static_cast<unsigned>((a >> 16) & 0xffff), static_cast<unsigned>(a & 0xfff),
                static_cast<unsigned>(0x8000 | ((b >> 48) & 0x3fff)),
                static_cast<unsigned long long>(b & 0xffffffffffffULL));
  return buf;
}

struct SimClient {
  SimVehicle vehicle;
  std::unique_ptr<mqtt::async_client> client;
  mqtt::token_ptr connect;
};

}  // namespace

void add_fleet_sim_options(CLI::App& app, FleetSimOptions& o) {
  app.add_option("--vehicles", o.vehicles, "number of simulated vehicles")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--broker", o.broker, "broker URI")->capture_default_str();
  app.add_option("--topic-prefix", o.topic_prefix, "topic prefix")->capture_default_str();
  app.add_option("--id-prefix", o.id_prefix, "vehicle ids are PREFIX<index>")
      ->capture_default_str();
  app.add_option("--first-index", o.first_index,
                 "index of the first vehicle (to split a fleet "
                 "over processes)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration-s", o.duration_s, "run this long (real time)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--riding-share", o.riding_share, "share of the fleet riding (the rest parked)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the simulated values")->capture_default_str();
}

int run_fleet_sim(const FleetSimOptions& o) {
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  const std::string uri = uplink::normalise_broker_uri(o.broker);
  uplink::ConnectionSettings settings;
  settings.broker_uri = uri;
  mqtt::connect_options opts = uplink::make_connect_options(settings);
  opts.set_mqtt_version(MQTTVERSION_5);
  opts.set_clean_start(false);
  opts.set_keep_alive_interval(30s);
  opts.set_properties(mqtt::properties{{mqtt::property::SESSION_EXPIRY_INTERVAL, 3600}});

  std::mt19937_64 ids(std::random_device{}());
  const auto riding = static_cast<int>(std::lround(o.vehicles * o.riding_share));
  const std::int64_t start = now_us();
  std::vector<SimClient> fleet;
  fleet.reserve(static_cast<std::size_t>(o.vehicles));
  for (int i = 0; i < o.vehicles; ++i) {
    const std::string id = o.id_prefix + std::to_string(o.first_index + i);
    SimVehicle v(id, random_store_id(ids), i < riding, o.seed * 7919u + static_cast<unsigned>(i),
                 start, o.topic_prefix);
    auto client =
        std::make_unique<mqtt::async_client>(uri, id, mqtt::create_options(MQTTVERSION_5));
    fleet.push_back({std::move(v), std::move(client), nullptr});
  }
  // Connect every session at once: Paho's threads are shared, a serial connect would take
  // minutes for a thousand.
  for (SimClient& s : fleet) s.connect = s.client->connect(opts);
  int connected = 0;
  for (SimClient& s : fleet) {
    try {
      if (s.connect->wait_for(60s)) ++connected;
    } catch (const mqtt::exception& e) {
      spdlog::warn("fleet-sim: {} could not connect: {}", s.vehicle.vehicle_id(), e.what());
    }
  }
  spdlog::info("fleet-sim: {} of {} vehicles connected ({} riding)", connected, o.vehicles, riding);

  std::int64_t messages = 0, records = 0, bytes = 0, failed = 0;
  // Bytes of the MQTT 5 PUBLISH packets each class of vehicle sends (fixed header, topic,
  // packet id, empty properties, payload): the radio's cost, without CONNECT and pings.
  std::int64_t riding_packet_bytes = 0, parked_packet_bytes = 0;
  std::deque<mqtt::delivery_token_ptr> pending;
  auto publish = [&](SimClient& s, std::vector<SimMessage> out) {
    for (SimMessage& m : out) {
      bytes += static_cast<std::int64_t>(m.topic.size() + m.payload.size());
      const std::size_t remaining = 2 + m.topic.size() + 2 + 1 + m.payload.size();
      const std::size_t varint = remaining < 128 ? 1 : remaining < 16384 ? 2 : 3;
      (s.vehicle.riding() ? riding_packet_bytes : parked_packet_bytes) +=
          static_cast<std::int64_t>(1 + varint + remaining);
      records += static_cast<std::int64_t>(m.records);
      ++messages;
      try {
        pending.push_back(
            s.client->publish(m.topic, m.payload.data(), m.payload.size(), 1, m.retained));
      } catch (const mqtt::exception& e) {
        ++failed;
        spdlog::debug("fleet-sim: publish from {} failed: {}", s.vehicle.vehicle_id(), e.what());
      }
    }
  };
  auto settle = [&] {
    while (!pending.empty() && pending.front()->is_complete()) {
      if (pending.front()->get_return_code() != 0) ++failed;
      pending.pop_front();
    }
  };

  const std::int64_t end = start + static_cast<std::int64_t>(o.duration_s * 1e6);
  for (;;) {
    const std::int64_t now = now_us();
    if (now >= end) break;
    for (SimClient& s : fleet) {
      if (now >= s.vehicle.next_due()) publish(s, s.vehicle.due(now));
    }
    settle();
    timespec tick{0, 50'000'000};
    if (sigtimedwait(&stop_signals, nullptr, &tick) > 0) break;
  }
  const std::int64_t stop = now_us();
  for (SimClient& s : fleet) publish(s, s.vehicle.drain(stop));
  for (const auto& t : pending) {
    try {
      if (!t->wait_for(30s) || t->get_return_code() != 0) ++failed;
    } catch (const mqtt::exception&) {
      ++failed;
    }
  }
  for (SimClient& s : fleet) {
    try {
      s.client->disconnect()->wait_for(5s);
    } catch (const mqtt::exception&) {
    }
  }

  nlohmann::json stores = nlohmann::json::array();
  for (const SimClient& s : fleet) {
    stores.push_back({{"vehicle_id", s.vehicle.vehicle_id()},
                      {"store_id", s.vehicle.store_id()},
                      {"last_sequence", s.vehicle.last_sequence()}});
  }
  const nlohmann::json report = {{"vehicles", o.vehicles},
                                 {"riding", riding},
                                 {"connected", connected},
                                 {"duration_s", static_cast<double>(stop - start) / 1e6},
                                 {"messages", messages},
                                 {"records", records},
                                 {"payload_bytes", bytes},
                                 {"riding_packet_bytes", riding_packet_bytes},
                                 {"parked_packet_bytes", parked_packet_bytes},
                                 {"unacknowledged", failed},
                                 {"stores", stores}};
  std::cout << report.dump() << std::endl;
  return connected == o.vehicles && failed == 0 ? 0 : 1;
}

}  // namespace fleetgw::app
