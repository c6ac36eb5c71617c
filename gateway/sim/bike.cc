// The simulated bike: construction (every node's periodic schedule), the bus output path and
// the public interface. The node logic is in bike_messages.cc and bike_behaviour.cc, the
// physics in ride_physics.cc; the shared Impl declaration in bike_impl.h.

#include "gateway/sim/bike.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "gateway/sim/bike_impl.h"
#include "motinova/segmenter.h"

namespace fleetgw::sim {

using namespace detail;

Bike::Impl::Impl(Scenario scenario) : sc_(std::move(scenario)), rng_(sc_.seed), now_(sc_.start) {
  opts_.crc_order = sc_.crc_order;
  opts_.data_order = sc_.data_order;
  rx_.set_crc_order(motinova::CrcOrder::kAuto);  // hear the gateway whichever CRC order it uses

  assist_ = sc_.initial_assist;
  headlight_ = sc_.headlight;
  vehicle_locked_ = sc_.vehicle_locked;
  ride_.odo_m = sc_.odo_km * 1000.0;
  ride_.full_mah = sc_.capacity_mah * (sc_.soh_pct / 100.0);
  ride_.remaining_mah = ride_.full_mah * sc_.soc_pct / 100.0;
  ride_.pack_v = cell_ocv(sc_.soc_pct) * kSeriesCells;
  ride_.batt_temp = ride_.motor_temp = sc_.ambient_c;
  ride_.pcb_temp = sc_.ambient_c + 3;
  ride_.mcu_temp = sc_.ambient_c + 5;
  ride_.max_temp = ride_.min_temp = sc_.ambient_c;
  tuning_.fill(0);
  std::fill(tuning_.begin(), tuning_.begin() + 20, uint8_t{100});

  // Manufacturing spread of the cells: a few mV around the mean, zero-sum so the cells still
  // add up to the pack voltage.
  double mean = 0;
  for (double& s : cell_spread_mv_) mean += (s = uniform(-8, 8));
  mean /= kSeriesCells;
  for (double& s : cell_spread_mv_) s -= mean;

  for (std::size_t i = 0; i < kSimLocks; ++i) {
    LockSim& l = locks_[i];
    l.node = motinova::lock_node(static_cast<int>(i));
    l.fitted = sc_.lock_fitted(i);
    l.state = sc_.locks_locked ? LockState::kLocked : LockState::kUnlocked;
    l.voltage_mv = 12'000 + uniform(-150, 150);
  }

  Micros end{0};
  for (const RideSegment& seg : sc_.ride) {
    const Micros begin = end;
    end += Micros(static_cast<int64_t>(std::llround(seg.duration_s * 1e6)));
    segment_ends_.push_back(end);
    if (seg.assist) {
      // The rider selects the level on the OBC, which tells the MC (0x731/0x3002).
      const uint8_t level = *seg.assist;
      at(sc_.start + begin + ms(20), [this, level] {
        send(Node::kObc,
             writer(0x731, 0x30).raw("assist", level).boolean("headlight", headlight_).frame());
      });
    }
  }
  for (const ScenarioEvent& ev : sc_.events) {
    at(sc_.start + ev.at, [this, ev] { apply(ev); });
  }

  const Micros t0 = sc_.start;
  periodic(t0, ms(100), [this] { step_physics(); });
  // MC (node 1)
  periodic(t0 + ms(7), ms(200), [this] { send_mc_status(); });
  periodic(t0 + ms(11), ms(200), [this] { fault_tick(Node::kMc); });
  periodic(t0 + ms(113), ms(1000), [this] { send_mc_odometer(); });
  periodic(t0 + ms(517), ms(5000), [this] { send_device_info(Node::kMc, 0x710, 0x12, sc_.mc); });
  // BMS (node 2)
  periodic(t0 + ms(31), ms(500), [this] { send_bms_status(); });
  periodic(t0 + ms(43), ms(200), [this] { fault_tick(Node::kBms); });
  periodic(t0 + ms(157), ms(1000), [this] { send_bms_cells(); });
  periodic(t0 + ms(307), ms(1000), [this] { send_bms_temps(); });
  periodic(t0 + ms(1201), ms(5000), [this] { send_bms_nameplate(); });
  periodic(t0 + ms(2203), ms(5000), [this] { send_device_info(Node::kBms, 0x720, 0x15, sc_.bms); });
  // OBC (node 3)
  periodic(t0 + ms(71), ms(200), [this] { fault_tick(Node::kObc); });
  periodic(t0 + ms(3301), ms(5000), [this] { send_device_info(Node::kObc, 0x730, 0x11, sc_.obc); });
  // Locks (nodes 7..B)
  for (std::size_t i = 0; i < kSimLocks; ++i) {
    if (!locks_[i].fitted) continue;
    const Node n = locks_[i].node;
    periodic(t0 + ms(400 + 37 * static_cast<int64_t>(i)), ms(1000),
             [this, i] { send_lock_status(i); });
    periodic(t0 + ms(89 + 13 * static_cast<int64_t>(i)), ms(200), [this, n] { fault_tick(n); });
  }

  at(t0, [this] { boot(); });
}

// ---------------------------------------------------------------------------------------------
// Bus

void Bike::Impl::send(Node src, const AppFrame& frame) {
  if (!alive(src)) {
    ++stats_.suppressed;
    return;
  }
  ++stats_.messages_sent;
  std::array<uint8_t, motinova::kMaxFrameSize> buf{};
  const std::size_t n = motinova::encode_frame(frame, sc_.crc_order, buf);
  std::vector<CanFrame> segs =
      motinova::segment(frame.can_id, std::span<const uint8_t>(buf.data(), n));

  const auto it = std::find_if(corruptions_.begin(), corruptions_.end(), [&](const auto& c) {
    return c.node == src || c.node == Node::kBroadcast;
  });
  if (it != corruptions_.end()) {
    if (it->kind == Corruption::kBitFlip) {
      CanFrame& seg = segs[static_cast<std::size_t>(uniform(0, static_cast<double>(segs.size())))];
      const auto byte = static_cast<std::size_t>(uniform(0, seg.len));
      const auto bit = static_cast<unsigned>(uniform(0, 8));
      seg.data[byte] = static_cast<uint8_t>(seg.data[byte] ^ (1u << bit));
      ++stats_.corrupted_bitflip;
    } else {
      segs.resize(std::max<std::size_t>(1, segs.size() / 2));  // frames are >= 11 bytes: 2+ segs
      ++stats_.corrupted_truncated;
    }
    corruptions_.erase(it);
  }
  for (const CanFrame& can : segs) put(can);
}

void Bike::Impl::garbage(uint32_t count) {
  for (uint32_t k = 0; k < count; ++k) {
    after(ms(2) * k, [this] {
      CanFrame can;
      can.id = 0x700 + static_cast<uint32_t>(uniform(0, 256));
      can.len = static_cast<uint8_t>(1 + uniform(0, 8));
      for (std::size_t i = 0; i < can.len; ++i) can.data[i] = static_cast<uint8_t>(uniform(0, 256));
      if (can.len >= 2 && can.data[0] == motinova::kHeader0 && can.data[1] == motinova::kHeader1) {
        can.data[0] = 0x00;  // garbage, not a message start
      }
      ++stats_.garbage_frames;
      put(can);
    });
  }
}

BikeState Bike::Impl::state() const {
  BikeState s;
  s.powered = powered_;
  s.speed_kmh = ride_.speed_ms * 3.6;
  s.odo_m = ride_.odo_m;
  s.trip_m = ride_.trip_m;
  s.odo_riding_s = ride_.odo_riding_s;
  s.trip_riding_s = ride_.trip_riding_s;
  s.soc_pct = ride_.remaining_mah / ride_.full_mah * 100.0;
  s.remaining_mah = ride_.remaining_mah;
  s.pack_voltage_v = ride_.pack_v;
  s.pack_current_a = ride_.current_a;
  s.motor_power_w = ride_.motor_w;
  s.energy_out_wh = ride_.energy_out_wh;
  s.energy_in_wh = ride_.energy_in_wh;
  s.battery_temp_c = ride_.batt_temp;
  s.motor_temp_c = ride_.motor_temp;
  s.assist = assist_;
  s.headlight = headlight_;
  s.vehicle_locked = vehicle_locked_;
  s.charging = ride_.charger_a > 0 && ride_.current_a > 0.01;
  s.speed_limit_offset_kmh = speed_limit_offset_;
  s.mc_faults = mc_faults_;
  s.bms_faults = bms_faults_;
  s.obc_faults = obc_faults_;
  for (std::size_t i = 0; i < kSimLocks; ++i) {
    s.lock_faults[i] = locks_[i].faults;
    s.lock_states[i] = locks_[i].state;
  }
  s.bms_handshake_ok = bms_ok_;
  s.obc_handshake_ok = obc_ok_;
  return s;
}

// ---------------------------------------------------------------------------------------------

Bike::Bike(Scenario scenario) : impl_(std::make_unique<Impl>(std::move(scenario))) {}
Bike::~Bike() = default;
Bike::Bike(Bike&&) noexcept = default;
Bike& Bike::operator=(Bike&&) noexcept = default;

void Bike::receive(const motinova::CanFrame& frame, Micros now) {
  impl_->receive(frame, now);
}
void Bike::advance_to(Micros now, const Emit& emit) {
  impl_->advance_to(now, emit);
}
Micros Bike::next_event() const {
  return impl_->next_event();
}
Micros Bike::current_time() const {
  return impl_->current_time();
}
void Bike::set_acc(bool on, Micros now) {
  impl_->set_acc(on, now);
}
BikeState Bike::state() const {
  return impl_->state();
}
const BikeStats& Bike::stats() const {
  return impl_->stats();
}
const Scenario& Bike::scenario() const {
  return impl_->scenario();
}

}  // namespace fleetgw::sim
