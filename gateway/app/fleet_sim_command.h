// `fleetgw fleet-sim`: N simulated vehicles, each with its own MQTT 5 session (client id = the
// vehicle id, persistent session, QoS 1), publishing the traffic of fleet_sim_model.h in real
// time against a broker: what a fleet costs the broker and `fleetgw ingest`.
//
// Contract:
//  * Vehicles are "<id-prefix><first-index + i>"; the first round(N * riding_share) ride, the
//    rest are parked, for the whole run. Each run uses a new store id per vehicle, so runs never
//    collide in the backend.
//  * Runs for `duration_s` (or until SIGINT/SIGTERM), then drains the pending telemetry batches
//    (as a clean stop of the gateway does), waits up to 30 s for every publish to be
//    acknowledged and disconnects.
//  * Prints one JSON object on stdout: vehicles, connected, messages, records, payload_bytes,
//    unacknowledged, and `stores`: per vehicle its store_id and last_sequence (the records it
//    created are 1..last_sequence: what an exactly-once check compares the backend with).
//    Exit status 0, or 1 when a vehicle could not connect or a publish was not acknowledged.
#pragma once

#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace fleetgw::app {

struct FleetSimOptions {
  int vehicles = 10;
  std::string broker = "tcp://127.0.0.1:1883";
  std::string topic_prefix = "fleet/v1";
  std::string id_prefix = "sim-bike-";
  int first_index = 0;
  double duration_s = 60;
  double riding_share = 0.3;
  std::uint32_t seed = 1;
};

void add_fleet_sim_options(CLI::App& app, FleetSimOptions& options);

int run_fleet_sim(const FleetSimOptions& options);

}  // namespace fleetgw::app
