// One simulated vehicle's traffic (fleet_sim_model.h).
#include "backend/fleet_sim/fleet_sim_model.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "fleetgw/v1/device_info.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "fleetgw/v1/lock.pb.h"
#include "fleetgw/v1/pack.pb.h"
#include "fleetgw/v1/ride.pb.h"
#include "fleetgw/v1/state.pb.h"
#include "fleetgw/v1/status.pb.h"

namespace fleetgw::fleet_sim {
namespace {

namespace v1 = fleetgw::v1;

// The default configuration's rates (config/fleetgw.toml).
constexpr std::int64_t kSecond = 1'000'000;
constexpr std::int64_t kRidingSample = 1 * kSecond;     // telemetry.riding_interval_ms
constexpr std::int64_t kParkedSample = 60 * kSecond;    // telemetry.parked_interval_ms
constexpr std::int64_t kRidingBatch = 5 * kSecond;      // mqtt.batch_max_ms
constexpr std::int64_t kParkedBatch = 300 * kSecond;    // parked.telemetry_batch_ms
constexpr std::size_t kBatchMaxSamples = 200;           // mqtt.batch_max_samples
constexpr std::int64_t kStateInterval = 5 * kSecond;    // mqtt.state_interval_ms
constexpr std::int64_t kStatusInterval = 60 * kSecond;  // mqtt.status_interval_ms
constexpr std::int64_t kPackInterval = 300 * kSecond;   // pack statistics
constexpr std::int64_t kRideLength = 900 * kSecond;     // a ride, then the next one
constexpr std::string_view kFirmware = FLEETGW_VERSION;
constexpr std::int64_t kBootSpread = 30 * kSecond;

void fill_header(v1::Envelope& e, std::string_view vehicle_id, std::uint64_t seq,
                 std::int64_t created_us, std::string_view store_id) {
  e.set_vehicle_id(std::string(vehicle_id));
  e.set_sequence(seq);
  e.set_created_at_us(created_us);
  e.set_gateway_fw_version(std::string(kFirmware));
  e.set_store_id(std::string(store_id));
}

}  // namespace

VehicleTopics::VehicleTopics(std::string_view prefix, std::string_view vehicle_id) {
  const std::string base = std::string(prefix) + "/" + std::string(vehicle_id);
  telemetry = base + "/telemetry";
  ride = base + "/ride";
  pack = base + "/pack";
  lock = base + "/lock";
  info = base + "/info";
  status = base + "/status";
  state = base + "/state";
}

SimVehicle::SimVehicle(std::string vehicle_id, std::string store_id, bool riding,
                       std::uint32_t seed, std::int64_t start_us, std::string_view topic_prefix)
    : vehicle_id_(std::move(vehicle_id)),
      store_id_(std::move(store_id)),
      riding_(riding),
      topics_(topic_prefix, vehicle_id_),
      rng_(seed) {
  std::uniform_real_distribution<double> u(0, 1);
  soc_ = 40 + 55 * u(rng_);
  odo_m_ = 100'000 + 3'000'000 * u(rng_);
  lat_e7_ = static_cast<std::int32_t>(523'000'000 + 2'000'000 * u(rng_));  // around Berlin
  lon_e7_ = static_cast<std::int32_t>(133'000'000 + 3'000'000 * u(rng_));
  // Gateways do not all boot in the same second: each vehicle starts at a random moment of the
  // first kBootSpread, and its periodic schedules have random phases (no thundering herd).
  boot_us_ = start_us + static_cast<std::int64_t>(u(rng_) * static_cast<double>(kBootSpread));
  auto phase = [&](std::int64_t period) {
    return boot_us_ + static_cast<std::int64_t>(u(rng_) * static_cast<double>(period));
  };
  next_sample_ = phase(riding_ ? kRidingSample : kParkedSample);
  next_state_ = phase(kStateInterval);
  next_status_ = boot_us_;
  next_pack_ = phase(kPackInterval);
  ride_start_ = boot_us_;
  ride_end_ = riding_ ? phase(kRideLength) : INT64_MAX;
}

std::int64_t SimVehicle::next_due() const {
  std::int64_t t = std::min({next_sample_, next_status_, next_pack_, ride_end_});
  if (riding_) t = std::min(t, next_state_);
  if (batch_.samples_size() > 0) t = std::min(t, batch_deadline_);
  return t;
}

v1::TelemetrySample SimVehicle::sample(std::int64_t now_us) {
  std::normal_distribution<double> noise(0, 1);
  if (riding_) {
    // City riding: 0..25 km/h around 18 with stops.
    speed_kmh_ = std::clamp(speed_kmh_ + 2 * noise(rng_) + 0.1 * (18 - speed_kmh_), 0.0, 25.0);
    const double dist = speed_kmh_ / 3.6 * (kRidingSample / static_cast<double>(kSecond));
    odo_m_ += dist;
    trip_m_ += dist;
    soc_ = std::max(5.0, soc_ - dist / 600.0 * 0.1);
    lat_e7_ += static_cast<std::int32_t>(dist * 90 * (noise(rng_) > 0 ? 1 : -1));
    lon_e7_ += static_cast<std::int32_t>(dist * 140);
  } else {
    speed_kmh_ = 0;
  }
  v1::TelemetrySample s;
  s.set_sampled_at_us(now_us);
  const auto speed = static_cast<std::uint32_t>(std::lround(speed_kmh_ * 10));
  s.set_speed_dkmh(speed);
  s.set_motor_rpm(speed * 9 / 10);
  const auto power =
      static_cast<std::int32_t>(riding_ ? 120 + 8 * speed_kmh_ + 20 * noise(rng_) : 0);
  s.set_power_w(power);
  s.set_voltage_mv(static_cast<std::uint32_t>(36000 + 60 * soc_));
  s.set_current_ma(power * 1000 / 40);
  s.set_cadence_rpm(riding_ ? static_cast<std::uint32_t>(55 + 10 * std::abs(noise(rng_))) : 0);
  s.set_torque_dnm(riding_ ? 150 : 0);
  s.set_assist(2);
  s.set_soc_pct(static_cast<std::uint32_t>(soc_));
  s.set_range_m(static_cast<std::uint32_t>(soc_ * 600) / 1000 * 1000);
  s.set_odo_m(static_cast<std::uint64_t>(odo_m_) / 100 * 100);
  s.set_trip_m(static_cast<std::uint64_t>(trip_m_) / 100 * 100);
  s.set_pcb_temp_c(31);
  s.set_motor_temp_c(riding_ ? 48 : 22);
  s.set_mcu_temp_c(35);
  s.set_remaining_mah(static_cast<std::uint32_t>(soc_ * 140));
  s.set_full_mah(14000);
  s.set_pack_temp_c(24);
  s.mutable_position()->set_lat_e7(lat_e7_);
  s.mutable_position()->set_lon_e7(lon_e7_);
  s.mutable_position()->set_fixed_at_us(now_us);
  return s;
}

v1::Envelope SimVehicle::record_envelope(std::int64_t now_us) {
  v1::Envelope e;
  fill_header(e, vehicle_id_, next_seq_++, now_us, store_id_);
  return e;
}

void SimVehicle::record(std::vector<SimMessage>& out, const std::string& topic,
                        const v1::Envelope& e) {
  out.push_back({topic, e.SerializeAsString(), false, 1});
}

void SimVehicle::flush_batch(std::vector<SimMessage>& out) {
  if (batch_.samples_size() == 0) return;
  const auto n = static_cast<std::uint64_t>(batch_.samples_size());
  v1::Envelope e;
  fill_header(e, vehicle_id_, batch_first_seq_, batch_first_us_, store_id_);
  e.mutable_telemetry()->Swap(&batch_);
  batch_.Clear();
  out.push_back({topics_.telemetry, e.SerializeAsString(), false, n});
}

std::string SimVehicle::state_envelope(std::int64_t now_us) {
  v1::Envelope e;
  fill_header(e, vehicle_id_, 0, now_us, store_id_);
  v1::VehicleState* s = e.mutable_state();
  s->set_updated_at_us(now_us);
  s->set_online(true);
  s->set_mode(riding_ ? v1::VEHICLE_MODE_RIDING : v1::VEHICLE_MODE_PARKED);
  v1::VehicleLock* lock = s->add_locks();
  lock->set_node("lock1");
  lock->set_kind("frame");
  lock->set_state(riding_ ? v1::LOCK_STATE_UNLOCKED : v1::LOCK_STATE_LOCKED);
  lock->set_state_name(riding_ ? "unlocked" : "locked");
  s->set_soc_pct(static_cast<std::uint32_t>(soc_));
  s->set_odo_m(static_cast<std::uint64_t>(odo_m_) / 100 * 100);
  s->mutable_position()->set_lat_e7(lat_e7_);
  s->mutable_position()->set_lon_e7(lon_e7_);
  s->set_bus_state(v1::BUS_STATE_ACTIVE);
  return e.SerializeAsString();
}

std::string SimVehicle::status_envelope(std::int64_t now_us) {
  v1::Envelope e;
  fill_header(e, vehicle_id_, 0, now_us, store_id_);
  v1::Status* s = e.mutable_status();
  s->set_state(v1::ONLINE_STATE_ONLINE);
  s->set_connection(v1::CONNECTION_STATE_CONNECTED);
  s->set_bus_state(v1::BUS_STATE_ACTIVE);
  s->set_firmware_version(std::string(kFirmware));
  s->set_last_publish_ok_at_us(now_us);
  return e.SerializeAsString();
}

std::vector<SimMessage> SimVehicle::due(std::int64_t now) {
  std::vector<SimMessage> out;
  if (now < boot_us_) return out;
  if (!info_sent_) {
    info_sent_ = true;
    v1::Envelope e = record_envelope(now);
    v1::DeviceInfo& info = *e.mutable_info();
    using Node = std::tuple<std::string_view, std::string_view, std::string_view>;
    for (const auto& [node, model, fw] :
         {Node{"iot", "FLEETGW-SIM", kFirmware}, Node{"mc", "MOTINOVA-MC", "V1.2.0"},
          Node{"bms", "MOTINOVA-BMS", "V2.0.1"}}) {
      v1::NodeInfo* n = info.add_nodes();
      n->set_node(std::string(node));
      n->set_model(std::string(model));
      n->set_fw_version(std::string(fw));
    }
    record(out, topics_.info, e);
  }
  if (now >= next_status_) {
    out.push_back({topics_.status, status_envelope(now), true, 0});
    next_status_ += kStatusInterval;
  }
  if (riding_ && now >= next_state_) {
    out.push_back({topics_.state, state_envelope(now), true, 0});
    next_state_ += kStateInterval;
  } else if (!riding_ && next_state_ != INT64_MAX && now >= next_state_) {
    out.push_back({topics_.state, state_envelope(now), true, 0});  // once: nothing changes
    next_state_ = INT64_MAX;
  }
  while (now >= next_sample_) {
    // The batch whose deadline this sample reaches leaves first (5 samples per riding batch).
    if (batch_.samples_size() > 0 && next_sample_ >= batch_deadline_) flush_batch(out);
    const std::uint64_t seq = next_seq_++;
    if (batch_.samples_size() == 0) {
      batch_first_seq_ = seq;
      batch_first_us_ = next_sample_;
      batch_deadline_ = next_sample_ + (riding_ ? kRidingBatch : kParkedBatch);
    }
    v1::TelemetrySample& s = *batch_.add_samples();
    s = sample(next_sample_);
    s.set_sequence(seq);
    if (static_cast<std::size_t>(batch_.samples_size()) >= kBatchMaxSamples) flush_batch(out);
    next_sample_ += riding_ ? kRidingSample : kParkedSample;
  }
  if (batch_.samples_size() > 0 && now >= batch_deadline_) flush_batch(out);
  if (now >= next_pack_) {
    v1::Envelope e = record_envelope(now);
    v1::PackStatistics& p = *e.mutable_pack();
    p.set_pack_serial("SIM-" + vehicle_id_);
    p.set_measured_at_us(now);
    p.set_voltage_mv(static_cast<std::uint32_t>(36000 + 60 * soc_));
    p.set_discharge_current_ma(riding_ ? 4000 : 0);
    p.set_soc_pct(static_cast<std::uint32_t>(soc_));
    p.set_soh_pct(96);
    p.set_cycles(212);
    for (int i = 0; i < 10; ++i) p.add_cells_mv(3700 + static_cast<std::uint32_t>(soc_));
    p.add_temp_c(24);
    p.add_temp_c(25);
    record(out, topics_.pack, e);
    next_pack_ += kPackInterval;
  }
  if (now >= ride_end_) {
    auto lock_event = [&](v1::LockState from, v1::LockState to, const char* from_name,
                          const char* to_name) {
      v1::Envelope e = record_envelope(now);
      v1::LockEvent& l = *e.mutable_lock();
      l.set_node("lock1");
      l.set_lock_kind("frame");
      l.set_previous_state(from);
      l.set_state(to);
      l.set_previous_state_name(from_name);
      l.set_state_name(to_name);
      l.set_source(v1::LOCK_EVENT_SOURCE_REMOTE);
      l.set_at_us(now);
      record(out, topics_.lock, e);
    };
    lock_event(v1::LOCK_STATE_UNLOCKED, v1::LOCK_STATE_LOCKED, "unlocked", "locked");
    v1::Envelope e = record_envelope(now);
    v1::RideRecord& r = *e.mutable_ride();
    r.set_ride_id(vehicle_id_ + "-" + std::to_string(ride_start_));
    r.set_started_at_us(ride_start_);
    r.set_ended_at_us(now);
    r.set_duration_ms(static_cast<std::uint64_t>((now - ride_start_) / 1000));
    r.set_moving_time_ms(r.duration_ms() * 9 / 10);
    r.set_distance_odo_m(static_cast<std::uint64_t>(trip_m_) / 100 * 100);
    r.set_distance_integrated_m(static_cast<std::uint64_t>(trip_m_));
    r.set_max_speed_dkmh(250);
    r.set_avg_speed_dkmh(170);
    r.set_energy_mwh(static_cast<std::uint64_t>(trip_m_ * 10));
    r.set_energy_mah(static_cast<std::uint64_t>(trip_m_ / 4));
    r.set_soc_end_pct(static_cast<std::uint32_t>(soc_));
    record(out, topics_.ride, e);
    lock_event(v1::LOCK_STATE_LOCKED, v1::LOCK_STATE_UNLOCKED, "locked", "unlocked");
    trip_m_ = 0;
    ride_start_ = now;
    ride_end_ = now + kRideLength;
  }
  return out;
}

std::vector<SimMessage> SimVehicle::drain(std::int64_t /*now_us*/) {
  std::vector<SimMessage> out;
  flush_batch(out);
  return out;
}

}  // namespace fleetgw::fleet_sim
