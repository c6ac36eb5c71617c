// fleetgw-fleet-sim (`fleetgw fleet-sim` execs it): N simulated vehicles, each with its own
// MQTT 5 session (client id = the vehicle id, QoS 1, no session expiry: sim_shard.cc), publishing
// the traffic of fleet_sim_model.h in real time against a broker: what a fleet costs the broker and
// the ingest, and the sender's side of an exactly-once check.
//
// Contract:
//  * Vehicles are "<id-prefix><first-index + i>"; the first round(N * riding_share) ride, the
//    rest are parked, for the whole run. Each run uses a new store id per vehicle, so runs never
//    collide in the backend.
//  * The fleet is spread over `processes` processes (vehicle i in process i % processes), each
//    one event loop (epoll) driving its sessions through libmosquitto's external-loop API: no
//    thread per session. Sessions connect at a steady `connect_rate` per second over the whole
//    fleet (vehicle i at i / connect_rate s); a vehicle powers on (its model's clock starts) at
//    that moment. With `source_addresses` K > 0, vehicle i connects from 127.0.0.(2 + (first_index
//    + i) % K), so a loopback fleet is not limited by one source address's ephemeral ports.
//  * Keep-alive is honoured under load: every session's PINGREQ is sent within one second of
//    falling due (libmosquitto's loop_misc for every session at least once a second).
//  * A vehicle is its bike's outbox: a QoS 1 message stays queued until its PUBACK; after a
//    reconnect every message not acknowledged is published again (a duplicate for the broker
//    when only the PUBACK was lost), and messages made while offline wait for the session.
//  * Runs for `duration_s` (or until SIGINT/SIGTERM), then drains the pending telemetry batches
//    (as a clean stop of the gateway does) and waits up to `stop_timeout_s` for every publish to
//    be acknowledged, then disconnects. A second signal ends the wait at once. The process exits
//    within stop_timeout_s + 5 s of the first signal whatever the broker does (a shard process
//    that has not ended by then is killed and reported as failed).
//  * Prints one JSON object on stdout (or writes it to `report`): vehicles, riding, connected
//    (vehicles whose session came up at least once), messages and records published (each
//    once), resent (publications repeated after a reconnect), disconnects (sessions lost while
//    running: the broker's keep-alive timeouts among them), unacknowledged (messages still queued
//    at exit), payload and packet bytes, and `stores`: per vehicle its store_id, last_sequence
//    (the records it created are 1..last_sequence) and unacknowledged. Exit status 0, or 1 when
//    a vehicle could not connect, a message was not acknowledged or a shard failed.
#pragma once

#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace fleetgw::fleet_sim {

struct FleetSimOptions {
  int vehicles = 10;
  std::string broker = "tcp://127.0.0.1:1883";
  std::string topic_prefix = "fleet/v1";
  std::string id_prefix = "sim-bike-";
  int first_index = 0;
  double duration_s = 60;
  double riding_share = 0.3;
  std::uint32_t seed = 1;
  int processes = 0;           // 0: one per 5,000 vehicles
  double connect_rate = 1000;  // new sessions per second, whole fleet
  int source_addresses = -1;   // -1: one per 5,000 vehicles against a 127.x broker, else none
  int keepalive_s = 30;        // the gateway's mqtt.keepalive_s
  double stop_timeout_s = 10;
  std::string report;  // empty: stdout
};

void add_fleet_sim_options(CLI::App& app, FleetSimOptions& options);

}  // namespace fleetgw::fleet_sim
