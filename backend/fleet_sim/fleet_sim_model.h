// The traffic of one simulated vehicle, as `fleetgw run` would publish it with the default
// configuration (config/fleetgw.toml), for fleetgw-fleet-sim: what a fleet costs a broker and
// the ingest. Pure: no clock, no I/O; the caller passes `now` (µs since the epoch) and publishes
// what comes out. Depends on proto/ only (the backend never builds against gateway/).
//
// Contract:
//  * A riding vehicle samples telemetry every telemetry.riding_interval_ms (1 s) and sends a
//    batch when its oldest sample is mqtt.batch_max_ms (5 s) old or it holds batch_max_samples
//    (200); a parked one samples every parked_interval_ms (60 s) and batches for
//    parked.telemetry_batch_ms (300 s). State (retained) every state_interval_ms (5 s) while
//    riding, once when parked; status (retained) at start and every 60 s; pack statistics every
//    300 s; DeviceInfo at start; riding vehicles close a ride every `ride_s` (lock event, ride
//    record, lock event for the next ride). A vehicle "boots" at a random moment of the first
//    30 s (DeviceInfo and its first status then); periodic schedules have random phases.
//  * Records carry the store's next sequence (from 1, contiguous across kinds, as the outbox
//    numbers them) and created_at_us = `now` at their creation.
//  * due(now) lists the messages to publish at `now` (possibly none); next_due() is the earliest
//    time something will be due. Topics are <prefix>/<vehicle_id>/<leaf> with the gateway's
//    leaves (uplink/topics.h); Envelopes carry the same header fields and bodies, a telemetry
//    batch its samples each with its own sequence (what the gateway's splicing writer produces,
//    byte for byte, from samples the generated code wrote). Values move plausibly (speed profile,
//    SOC draining, odometer, position drifting) from a seed, so runs are reproducible.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "fleetgw/v1/telemetry.pb.h"

namespace fleetgw::fleet_sim {

// The topics one vehicle publishes on (the gateway's uplink/topics.h leaves).
struct VehicleTopics {
  VehicleTopics(std::string_view prefix, std::string_view vehicle_id);
  std::string telemetry, ride, pack, lock, info, status, state;
};

struct SimMessage {
  std::string topic;
  std::string payload;
  bool retained = false;
  std::uint64_t records = 0;  // records carried (samples for telemetry)
};

class SimVehicle {
 public:
  SimVehicle(std::string vehicle_id, std::string store_id, bool riding, std::uint32_t seed,
             std::int64_t start_us, std::string_view topic_prefix = "fleet/v1");

  std::vector<SimMessage> due(std::int64_t now_us);
  std::int64_t next_due() const;
  // A clean stop: the pending batch leaves now (as the gateway drains on SIGTERM).
  std::vector<SimMessage> drain(std::int64_t now_us);

  const std::string& vehicle_id() const { return vehicle_id_; }
  bool riding() const { return riding_; }
  std::uint64_t last_sequence() const { return next_seq_ - 1; }
  const std::string& store_id() const { return store_id_; }

 private:
  v1::TelemetrySample sample(std::int64_t now_us);
  // A record Envelope with the next sequence; its body is set by the caller.
  v1::Envelope record_envelope(std::int64_t now_us);
  void record(std::vector<SimMessage>& out, const std::string& topic, const v1::Envelope& e);
  void flush_batch(std::vector<SimMessage>& out);
  std::string state_envelope(std::int64_t now_us);
  std::string status_envelope(std::int64_t now_us);

  std::string vehicle_id_;
  std::string store_id_;
  bool riding_;
  VehicleTopics topics_;
  std::mt19937 rng_;
  std::uint64_t next_seq_ = 1;
  // Values that move.
  double soc_ = 80;
  double odo_m_ = 1'000'000;
  double trip_m_ = 0;
  double speed_kmh_ = 0;
  std::int32_t lat_e7_ = 0;
  std::int32_t lon_e7_ = 0;
  // Schedules (µs since the epoch).
  std::int64_t boot_us_;
  std::int64_t next_sample_;
  std::int64_t next_state_;
  std::int64_t next_status_;
  std::int64_t next_pack_;
  std::int64_t ride_end_;
  std::int64_t ride_start_;
  bool info_sent_ = false;
  v1::TelemetryBatch batch_;
  std::uint64_t batch_first_seq_ = 0;
  std::int64_t batch_first_us_ = 0;
  std::int64_t batch_deadline_ = 0;
};

}  // namespace fleetgw::fleet_sim
