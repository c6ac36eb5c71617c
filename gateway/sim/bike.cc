// The simulated bike. One Impl holds every node; nodes interact only through frames on the
// (internal) bus, exactly as the real ones do, so the gateway sees the same causal chains
// (HANDSHAKE -> READY, SHUTDOWN -> READY, UNLOCK -> unlocking -> unlocked).

#include "gateway/sim/bike.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/faults.h"
#include "motinova/frame.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"

namespace fleetgw::sim {
namespace {

using motinova::AppFrame;
using motinova::CanFrame;
using motinova::Node;

constexpr Micros ms(int64_t v) {
  return Micros(v * 1000);
}
constexpr Micros kNever = Micros::max();

// Physical constants of the model (docs/simulator.md, "Physics").
constexpr double kMassKg = 100;  // bike 25 kg + rider 75 kg
constexpr double kGravity = 9.81;
constexpr double kCrr = 0.008;  // rolling resistance
constexpr double kCdA = 0.55;   // drag area, upright city position
constexpr double kAirDensity = 1.2;
constexpr double kMaxAccel = 1.0;   // m/s², gentle city acceleration
constexpr double kMaxBrake = 2.0;   // m/s²
constexpr double kMotorMaxW = 500;  // peak mechanical assist
constexpr double kMotorEfficiency = 0.8;
constexpr double kStandbyW = 5;  // MC + OBC + locks electronics while powered
constexpr double kHeadlightW = 3;
constexpr double kPackResistance = 0.12;  // ohm, 13S pack incl. wiring (IR drop)
constexpr int kSeriesCells = 13;
constexpr double kNominalPackV = 3.6 * kSeriesCells;
constexpr double kPhysicsStepS = 0.1;

// Open-circuit voltage of one Li-ion cell at SOC 0, 10, ... 100 %: 13S spans 39.0 .. 54.6 V.
constexpr double kCellOcv[] = {3.00, 3.45, 3.55, 3.62, 3.68, 3.74, 3.81, 3.89, 3.97, 4.07, 4.20};

double cell_ocv(double soc_pct) {
  const double x = std::clamp(soc_pct, 0.0, 100.0) / 10.0;
  const int i = std::min(9, static_cast<int>(x));
  return kCellOcv[i] + (kCellOcv[i + 1] - kCellOcv[i]) * (x - i);
}

// Assist ratio: motor power / rider power per assist level (enum §3.0).
double assist_ratio(uint8_t assist) {
  switch (assist) {
    case 0x01:
      return 0.5;
    case 0x02:
      return 1.0;
    case 0x03:
      return 1.7;
    case 0x04:
      return 2.6;
    case 0x22:
      return 1.2;
    case 0x33:
      return 1.4;
    default:
      return 0.0;  // off; walk is handled separately
  }
}

bool valid_assist(int64_t v) {
  return (v >= 0 && v <= 5) || v == 0x22 || v == 0x33;
}

int64_t clamp_raw(double v, int64_t lo, int64_t hi) {
  if (!std::isfinite(v)) return lo;
  return std::clamp<int64_t>(static_cast<int64_t>(std::llround(v)), lo, hi);
}

int64_t temp_raw(double c) {
  return clamp_raw(c + 40.0, 0, 255);
}

constexpr uint16_t broadcast_id(Node n) {
  return motinova::make_can_id(n, Node::kBroadcast);
}

// Lock fault bit raised when an actuation times out (0x0040, "perhaps motor stall/jam", U20).
constexpr uint32_t kLockStallBit = 0x0040;
// MC fault bits for failed start-up checks (§3.8.1).
constexpr uint32_t kMcBmsCheckBit = 0x0400;
constexpr uint32_t kMcObcCheckBit = 0x1000;

}  // namespace

class Bike::Impl final : public motinova::FrameSink {
 public:
  explicit Impl(Scenario scenario);

  void receive(const CanFrame& frame, Micros now) {
    ++stats_.external_frames;
    now = std::max(now, now_);
    // Nothing of ours is due before `now`: the clock may move on. (Otherwise the caller will
    // advance_to() later; reactions are timed from the frame's own timestamp either way.)
    if (next_event() > now) now_ = now;
    rx_.push(frame, now, *this);
  }

  void advance_to(Micros now, const Emit& emit) {
    emit_ = &emit;
    while (!queue_.empty() && queue_.front().at <= now) {
      std::pop_heap(queue_.begin(), queue_.end(), Later{});
      Event ev = std::move(queue_.back());
      queue_.pop_back();
      now_ = std::max(now_, ev.at);
      ev.fn();
    }
    now_ = std::max(now_, now);
    emit_ = nullptr;
  }

  Micros next_event() const { return queue_.empty() ? kNever : queue_.front().at; }
  Micros current_time() const { return now_; }

  void set_acc(bool on, Micros now) {
    now = std::max(now, now_);
    if (on) {
      at(now, [this] { power_on(); });
    } else {
      at(now, [this] { power_off(); });
    }
  }

  BikeState state() const;
  const BikeStats& stats() const { return stats_; }
  const Scenario& scenario() const { return sc_; }

  // motinova::FrameSink: the bike's own receive path (everything heard on the bus).
  void on_frame(const AppFrame& frame, Micros timestamp) override {
    reaction_base_ = timestamp;
    handle(frame);
    reaction_base_ = Micros::min();
  }
  void on_error(const motinova::ReassemblyErrorEvent&) override { ++stats_.rx_errors; }

 private:
  struct Event {
    Micros at;
    uint64_t seq;
    std::function<void()> fn;
  };
  struct Later {
    bool operator()(const Event& a, const Event& b) const {
      return a.at != b.at ? a.at > b.at : a.seq > b.seq;
    }
  };

  struct FaultTx {
    uint32_t last_sent = 0;
    Micros last_time{-1'000'000'000};
  };

  struct LockSim {
    Node node = Node::kLock1;
    bool fitted = false;
    LockState state = LockState::kLocked;
    bool jammed = false;
    uint32_t faults = 0;
    uint64_t generation = 0;  // bumps cancel a pending actuation step
    bool moving = false;
    double voltage_mv = 12'000;
    FaultTx fault_tx;
  };

  // ---- scheduling ----
  void at(Micros t, std::function<void()> fn) {
    queue_.push_back(Event{std::max(t, now_), seq_++, std::move(fn)});
    std::push_heap(queue_.begin(), queue_.end(), Later{});
  }
  // Relative to the current time, or to the receive time of the frame being handled.
  void after(Micros d, std::function<void()> fn) {
    at(std::max(now_, reaction_base_) + d, std::move(fn));
  }
  // Periodic task at first + k * period, each occurrence jittered by up to 1.5 ms (seeded) so
  // that nodes drift against each other as on a real bus, without accumulating drift.
  void periodic(Micros nominal, Micros period, std::function<void()> fn) {
    const Micros jitter(static_cast<int64_t>(uniform(0, 1500)));
    at(nominal + jitter, [this, nominal, period, fn = std::move(fn)]() mutable {
      fn();
      periodic(nominal + period, period, std::move(fn));
    });
  }
  Micros reply_latency() { return Micros(static_cast<int64_t>(uniform(3'000, 20'000))); }

  // ---- seeded randomness (own helpers: identical streams on every standard library) ----
  double unit() { return static_cast<double>(rng_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  double normal() {  // Irwin-Hall approximation, mean 0, variance 1
    double s = 0;
    for (int i = 0; i < 12; ++i) s += unit();
    return s - 6.0;
  }

  // ---- bus ----
  bool alive(Node n) const {
    const auto i = static_cast<std::size_t>(n);
    if (!powered_ || silent_[i] || switched_off_[i]) return false;
    if (motinova::is_lock(n))
      return locks_[static_cast<std::size_t>(motinova::lock_index(n))].fitted;
    return n == Node::kMc || n == Node::kBms || n == Node::kObc;
  }
  const motinova::MessageDesc& desc(uint16_t can_id, uint8_t function) const {
    const motinova::MessageDesc* d = motinova::Catalogue::standard().find(can_id, function);
    if (!d) {
      char text[80];
      std::snprintf(text, sizeof text, "sim: message 0x%03X function 0x%02X not in the catalogue",
                    static_cast<unsigned>(can_id), static_cast<unsigned>(function));
      throw std::logic_error(text);
    }
    return *d;
  }
  motinova::MessageWriter writer(uint16_t can_id, uint8_t function) const {
    return motinova::MessageWriter(desc(can_id, function), opts_);
  }
  void send(Node src, const AppFrame& frame);
  void put(const CanFrame& can) {
    ++stats_.can_frames_sent;
    if (emit_) (*emit_)(can);
    rx_.push(can, now_, *this);
  }
  void garbage(uint32_t count);

  // ---- node messages ----
  void send_mc_status();
  void send_mc_odometer();
  void send_device_info(Node src, uint16_t can_id, uint8_t function, const DeviceStrings& d,
                        std::string_view serial_suffix = {});
  void send_keyword(Node src, uint16_t can_id, uint8_t function) {
    send(src, writer(can_id, function).frame());
  }
  void send_mc_settings();
  void send_mc_params2();
  void send_mc_tuning();
  void send_bms_status();
  void send_bms_cells();
  void send_bms_nameplate();
  void send_bms_temps();
  void send_pack_stats();
  void send_lock_status(std::size_t i);
  void send_fault_word(Node n);
  uint32_t& fault_word(Node n);
  FaultTx& fault_tx(Node n);
  void fault_tick(Node n);
  void set_faults(Node n, uint32_t bits, bool on);

  // ---- behaviour ----
  void boot();
  void handshake_round(uint64_t boot_gen, int attempt);
  void power_on();
  void power_off();
  void shutdown_requested(Node initiator);
  void handle(const AppFrame& f);
  void handle_mc_command(const AppFrame& f, bool from_obc);
  void handle_lock_command(const AppFrame& f, std::size_t i);
  void actuate(std::size_t i, bool lock);
  void apply(const ScenarioEvent& ev);
  void step_physics();
  double profile_speed_kmh(Micros t_rel, double* grade) const;
  double effective_limit_kmh() const {
    return std::max(0.0, sc_.speed_limit_kmh + speed_limit_offset_);
  }
  bool assist_allowed() const;
  bool keyword_ok(const AppFrame& f) const {
    return decoded_.desc && decoded_.desc->kind == motinova::MessageKind::kKeyword &&
           std::equal(f.data.begin(), f.data.end(), decoded_.desc->keyword.begin(),
                      decoded_.desc->keyword.end());
  }

  Scenario sc_;
  motinova::DecodeOptions opts_;
  std::mt19937_64 rng_;
  motinova::Reassembler rx_;
  motinova::DecodedMessage decoded_;
  std::vector<Event> queue_;
  uint64_t seq_ = 0;
  Micros now_;
  const Emit* emit_ = nullptr;
  Micros reaction_base_ = Micros::min();  // receive time of the frame being handled
  BikeStats stats_;

  // power and links
  bool powered_ = true;
  uint64_t boot_gen_ = 0;
  uint64_t shutdown_gen_ = 0;
  std::array<bool, 16> silent_{};        // scenario: node dropped off the bus
  std::array<bool, 16> switched_off_{};  // node powered itself down (OBC after 0x763 SHUTDOWN)
  std::array<uint64_t, 16> silence_gen_{};
  struct PendingCorruption {
    Node node;
    Corruption kind;
  };
  std::vector<PendingCorruption> corruptions_;

  // MC
  bool bms_ok_ = false;
  bool obc_ok_ = false;
  uint8_t assist_ = 2;
  bool headlight_ = false;
  bool vehicle_locked_ = false;
  int speed_limit_offset_ = 0;
  int wheel_adjust_cm_ = 0;
  uint8_t mc_mode_ = 2;
  std::array<uint8_t, 5> params2_{0, 9, 50, 120, 30};  // selector, P1..P4 (P5 = 0)
  std::array<uint8_t, 32> tuning_{};
  uint32_t mc_faults_ = 0;
  FaultTx mc_fault_tx_;

  // ride / physics
  std::vector<Micros> segment_ends_;
  double speed_ms_ = 0;
  double wobble_kmh_ = 0;
  double odo_m_ = 0;
  double trip_m_ = 0;
  double odo_riding_s_ = 0;
  double trip_riding_s_ = 0;
  double trip_mah_ = 0;
  double trip_wh_ = 0;
  double cadence_ = 0;
  double torque_ = 0;
  double motor_w_ = 0;
  double motor_rpm_ = 0;
  double motor_temp_ = 20;
  double pcb_temp_ = 20;
  double mcu_temp_ = 20;

  // BMS
  double full_mah_ = 14'000;
  double remaining_mah_ = 0;
  double pack_v_ = 50;
  double current_a_ = 0;  // charge +
  double batt_temp_ = 20;
  double energy_out_wh_ = 0;
  double energy_in_wh_ = 0;
  double charger_a_ = 0;
  double charge_session_s_ = 0;
  double charge_total_s_ = 0;
  double charge_longest_s_ = 0;
  double runtime_s_ = 0;
  double max_temp_ = 20;
  double min_temp_ = 20;
  double max_discharge_ma_ = 0;
  double max_charge_ma_ = 0;
  std::array<double, kSeriesCells> cell_spread_mv_{};
  uint32_t bms_faults_ = 0;
  FaultTx bms_fault_tx_;

  // OBC
  uint32_t obc_faults_ = 0;
  FaultTx obc_fault_tx_;

  std::array<LockSim, kSimLocks> locks_{};
};

Bike::Impl::Impl(Scenario scenario) : sc_(std::move(scenario)), rng_(sc_.seed), now_(sc_.start) {
  opts_.crc_order = sc_.crc_order;
  opts_.data_order = sc_.data_order;
  rx_.set_crc_order(motinova::CrcOrder::kAuto);  // hear the gateway whichever CRC order it uses

  assist_ = sc_.initial_assist;
  headlight_ = sc_.headlight;
  vehicle_locked_ = sc_.vehicle_locked;
  odo_m_ = sc_.odo_km * 1000.0;
  full_mah_ = sc_.capacity_mah * (sc_.soh_pct / 100.0);
  remaining_mah_ = full_mah_ * sc_.soc_pct / 100.0;
  pack_v_ = cell_ocv(sc_.soc_pct) * kSeriesCells;
  batt_temp_ = motor_temp_ = sc_.ambient_c;
  pcb_temp_ = sc_.ambient_c + 3;
  mcu_temp_ = sc_.ambient_c + 5;
  max_temp_ = min_temp_ = sc_.ambient_c;
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

// ---------------------------------------------------------------------------------------------
// Messages

void Bike::Impl::send_mc_status() {
  const double v_kmh = speed_ms_ * 3.6;
  const double discharge_ma = std::max(0.0, -current_a_) * 1000.0;
  // Range and consumption from this trip once it is long enough to say anything.
  int64_t range_raw = 0xFFFF;
  int64_t consumption_raw = 0xFF;
  const double remaining_wh = remaining_mah_ / 1000.0 * kNominalPackV;
  const double wh_per_km = trip_m_ > 500 ? std::max(2.0, trip_wh_ / (trip_m_ / 1000.0)) : 9.0;
  range_raw = clamp_raw(remaining_wh / wh_per_km, 0, 0xFFFE);
  if (trip_m_ >= 100) consumption_raw = clamp_raw(trip_mah_ / (trip_m_ / 1000.0) / 10.0, 0, 0xFE);
  send(Node::kMc,
       writer(0x710, 0x10)
           .raw("speed_kmh", clamp_raw(v_kmh * 10, 0, 0xFFFF))
           .raw("motor_rpm", clamp_raw(motor_rpm_, 0, 0xFFFF))
           .raw("power_w", clamp_raw(motor_w_, 0, 0xFFFF))
           .raw("voltage_v", clamp_raw(pack_v_ * 1000, 0, 0xFFFF))
           .raw("current_a", clamp_raw(discharge_ma, 0, 0xFFFF))
           .raw("cadence_rpm", clamp_raw(cadence_, 0, 255))
           .raw("torque_nm", clamp_raw(torque_, 0, 255))
           .raw("direction", v_kmh > 0.05 ? 0 : 2)
           .raw("assist", assist_)
           .boolean("headlight", headlight_)
           .raw("soc_pct", clamp_raw(remaining_mah_ / full_mah_ * 100, 0, 100))
           .raw("range_km", range_raw)
           .raw("odo_km", std::min<int64_t>(static_cast<int64_t>(odo_m_ / 1000), 0xFFFF))
           .raw("consumption_ah_per_km", consumption_raw)
           .raw("pcb_temp_c", temp_raw(pcb_temp_))
           .raw("motor_temp_c", temp_raw(motor_temp_))
           .raw("mcu_temp_c", temp_raw(mcu_temp_))
           .raw("trip_km", std::min<int64_t>(static_cast<int64_t>(trip_m_ / 100), 0xFFFF))
           .raw("trip_time_s", std::min<int64_t>(static_cast<int64_t>(trip_riding_s_), 0xFFFF))
           .frame());
}

void Bike::Impl::send_mc_odometer() {
  send(Node::kMc, writer(0x710, 0x15)
                      .raw("odo_km", static_cast<int64_t>(odo_m_ / 100))
                      .raw("odo_time_min", static_cast<int64_t>(odo_riding_s_ / 60))
                      .raw("trip_km", static_cast<int64_t>(trip_m_ / 100))
                      .raw("trip_time_min", static_cast<int64_t>(trip_riding_s_ / 60))
                      .frame());
}

void Bike::Impl::send_device_info(Node src, uint16_t can_id, uint8_t function,
                                  const DeviceStrings& d, std::string_view serial_suffix) {
  send(src, writer(can_id, function)
                .text("model", d.model)
                .text("serial", d.serial + std::string(serial_suffix))
                .text("hw", d.hw)
                .text("fw", d.fw)
                .frame());
}

void Bike::Impl::send_mc_settings() {
  send(Node::kMc, writer(0x713, 0x54)
                      .raw("wheel_size_cm", sc_.wheel_circumference_cm)
                      .raw("mode", mc_mode_)
                      .raw("speed_limit_kmh", clamp_raw(sc_.speed_limit_kmh, 0, 255))
                      .raw("wheel_adjust_cm", wheel_adjust_cm_)
                      .raw("speed_limit_offset_kmh", speed_limit_offset_)
                      .frame());
}

void Bike::Impl::send_mc_params2() {
  send(Node::kMc, writer(0x713, 0x55)
                      .raw("selector", params2_[0])
                      .raw("p1", params2_[1])
                      .raw("p2", params2_[2])
                      .raw("p3", params2_[3])
                      .raw("p4_min", params2_[4])
                      .raw("p5", 0)
                      .frame());
}

void Bike::Impl::send_mc_tuning() {
  AppFrame f = writer(0x713, 0x56).frame();
  std::copy(tuning_.begin(), tuning_.end(), f.data.data());
  send(Node::kMc, f);
}

void Bike::Impl::send_bms_status() {
  uint8_t flags = 0;
  int64_t charge_min = 0;
  if (current_a_ > 0.01 && charger_a_ > 0) {
    flags |= 0x01;  // charging
    charge_min = clamp_raw((full_mah_ - remaining_mah_) / (current_a_ * 1000.0) * 60.0, 0, 0xFFFF);
  }
  const double current_ma = current_a_ * 1000.0 * (opts_.bms_current_charge_positive ? 1 : -1);
  send(Node::kBms, writer(0x720, 0x10)
                       .raw("voltage_v", clamp_raw(pack_v_ * 1000, 0, 0xFFFF))
                       .raw("current_a", clamp_raw(current_ma, -32768, 32767))
                       .raw("remaining_mah", clamp_raw(remaining_mah_, 0, 0xFFFF))
                       .raw("full_mah", clamp_raw(full_mah_, 0, 0xFFFF))
                       .raw("temp_c", temp_raw(batt_temp_))
                       .raw("soc_pct", clamp_raw(remaining_mah_ / full_mah_ * 100, 0, 100))
                       .raw("state_flags", flags)
                       .raw("soh_pct", sc_.soh_pct)
                       .raw("cycles", sc_.cycles)
                       .raw("charge_time_min", charge_min)
                       .frame());
}

void Bike::Impl::send_bms_cells() {
  motinova::MessageWriter w = writer(0x720, 0x11);
  const double mean_mv = pack_v_ * 1000.0 / kSeriesCells;
  for (std::size_t i = 0; i < kSeriesCells; ++i) {
    w.element("cells_mv", i,
              static_cast<uint64_t>(clamp_raw(mean_mv + cell_spread_mv_[i], 0, 0xFFFF)));
  }
  send(Node::kBms, w.frame());  // cells 14..16 stay 0: a 13S pack
}

void Bike::Impl::send_bms_nameplate() {
  send(Node::kBms, writer(0x720, 0x14)
                       .raw("rated_capacity_mah", sc_.capacity_mah)
                       .raw("rated_voltage_v", 48)
                       .text("date_text", "24/05/03")
                       .raw("max_current_a", 20)
                       .frame());
}

void Bike::Impl::send_bms_temps() {
  // Hottest / coolest cell around the pack temperature; the two u16 values are illegible in
  // the spec (U22): the sim sends minutes since power-on and minutes of the charge session.
  send(Node::kBms, writer(0x720, 0x18)
                       .raw("temp_max_c", temp_raw(batt_temp_ + 1.5))
                       .raw("temp_min_c", temp_raw(batt_temp_ - 1.0))
                       .raw("value_1", clamp_raw(runtime_s_ / 60, 0, 0xFFFF))
                       .raw("time_2", clamp_raw(charge_session_s_ / 60, 0, 0xFFFF))
                       .frame());
}

void Bike::Impl::send_pack_stats() {
  send(Node::kBms, writer(0x725, 0x50)
                       .raw("max_temp_c", temp_raw(max_temp_))
                       .raw("min_temp_c", temp_raw(min_temp_))
                       .raw("max_discharge_current_a", clamp_raw(max_discharge_ma_, 0, 0xFFFF))
                       .raw("max_charge_current_a", clamp_raw(max_charge_ma_, 0, 0xFFFF))
                       .raw("cycles", sc_.cycles)
                       .raw("charge_time_total_h", clamp_raw(charge_total_s_ / 3600, 0, 0xFFFF))
                       .raw("charge_time_longest_h", clamp_raw(charge_longest_s_ / 3600, 0, 0xFFFF))
                       .raw("runtime_min", clamp_raw(runtime_s_ / 60, 0, 0xFFFFFFFF))
                       .raw("soh_pct", sc_.soh_pct)
                       .frame());
}

void Bike::Impl::send_lock_status(std::size_t i) {
  const LockSim& l = locks_[i];
  const uint16_t id = broadcast_id(l.node);
  // Bolt bit 0 = 1 while the bolt is thrown (locked); the polarity is U20.
  const bool bolt = l.state == LockState::kLocked || l.state == LockState::kUnlockFailed ||
                    l.state == LockState::kUnlocking;
  motinova::MessageWriter w = writer(id, 0x10);
  w.raw("voltage_v", clamp_raw(l.voltage_mv - (l.moving ? 250 : 0), 0, 0xFFFF))
      .raw("current_a", l.moving ? 620 : 12)
      .raw("temp_c", temp_raw(sc_.ambient_c + (l.moving ? 4 : 2)))
      .raw("state", static_cast<int64_t>(l.state))
      .raw("bolts", bolt ? 1 : 0);
  if (l.node == Node::kLock4) w.raw("motor_rpm", l.moving ? 2400 : 0);
  send(l.node, w.frame());
}

uint32_t& Bike::Impl::fault_word(Node n) {
  switch (n) {
    case Node::kMc:
      return mc_faults_;
    case Node::kBms:
      return bms_faults_;
    case Node::kObc:
      return obc_faults_;
    default:
      return locks_.at(static_cast<std::size_t>(motinova::lock_index(n))).faults;
  }
}

Bike::Impl::FaultTx& Bike::Impl::fault_tx(Node n) {
  switch (n) {
    case Node::kMc:
      return mc_fault_tx_;
    case Node::kBms:
      return bms_fault_tx_;
    case Node::kObc:
      return obc_fault_tx_;
    default:
      return locks_.at(static_cast<std::size_t>(motinova::lock_index(n))).fault_tx;
  }
}

void Bike::Impl::send_fault_word(Node n) {
  uint16_t id = broadcast_id(n);
  uint8_t function = 0x11;  // MC and locks
  if (n == Node::kBms) function = 0x12;
  if (n == Node::kObc) function = 0x15;
  const uint32_t word = fault_word(n);
  FaultTx& tx = fault_tx(n);
  tx.last_sent = word;
  tx.last_time = now_;
  send(n, writer(id, function).raw("raw", word).frame());
}

// §3.7 (U12): every 200 ms while a fault is present, every 1 s when all is well, and at once on
// a change (set_faults).
void Bike::Impl::fault_tick(Node n) {
  const FaultTx& tx = fault_tx(n);
  if (fault_word(n) != 0 || now_ - tx.last_time >= ms(990)) send_fault_word(n);
}

void Bike::Impl::set_faults(Node n, uint32_t bits, bool on) {
  uint32_t& word = fault_word(n);
  const uint32_t before = word;
  word = on ? (word | bits) : (word & ~bits);
  if (word != before) after(ms(2), [this, n] { send_fault_word(n); });
}

// ---------------------------------------------------------------------------------------------
// Behaviour

void Bike::Impl::boot() {
  ++boot_gen_;
  bms_ok_ = obc_ok_ = false;
  const uint64_t gen = boot_gen_;
  after(ms(50), [this, gen] { handshake_round(gen, 0); });
}

// §3.8.1: the MC checks the BMS and the OBC at start-up. Three tries 300 ms apart, then the
// check-fault bits are raised (and the MC stops assisting) while it keeps asking every 2 s.
void Bike::Impl::handshake_round(uint64_t boot_gen, int attempt) {
  if (boot_gen != boot_gen_ || !powered_) return;
  if (bms_ok_ && obc_ok_) return;
  if (!alive(Node::kMc)) {
    after(ms(300), [this, boot_gen, attempt] { handshake_round(boot_gen, attempt); });
    return;
  }
  if (attempt >= 3) {
    set_faults(Node::kMc, kMcBmsCheckBit, !bms_ok_);
    set_faults(Node::kMc, kMcObcCheckBit, !obc_ok_);
  }
  if (!bms_ok_) send_keyword(Node::kMc, 0x712, 0x30);
  if (!obc_ok_) send_keyword(Node::kMc, 0x713, 0x50);
  const Micros wait = attempt >= 3 ? ms(2000) : ms(300);
  after(wait, [this, boot_gen, attempt] { handshake_round(boot_gen, attempt + 1); });
}

void Bike::Impl::power_on() {
  if (powered_) return;
  powered_ = true;
  switched_off_.fill(false);
  boot();
}

void Bike::Impl::power_off() {
  if (!powered_) return;
  powered_ = false;
  ++boot_gen_;
  ++shutdown_gen_;
  for (LockSim& l : locks_) {
    if (l.moving) {  // power cut mid-actuation: the lock stops where it is
      ++l.generation;
      l.moving = false;
      l.state = l.state == LockState::kLocking ? LockState::kLockFailed : LockState::kUnlockFailed;
    }
  }
}

// §3.8.2: MC and OBC save their state and answer READY; the IOT is expected to answer too
// (that is the gateway's job, not the sim's).
void Bike::Impl::shutdown_requested(Node initiator) {
  if (alive(Node::kMc)) after(reply_latency(), [this] { send_keyword(Node::kMc, 0x710, 0x13); });
  if (initiator != Node::kObc && alive(Node::kObc)) {
    after(reply_latency(), [this] { send_keyword(Node::kObc, 0x730, 0x14); });
  }
  if (initiator == Node::kIot && !sc_.iot_controls_acc) return;
  // The initiator removes power about 1 s later: OBC and BMS themselves, the IOT via ACC.
  const uint64_t gen = ++shutdown_gen_;
  after(ms(1200), [this, gen] {
    if (gen == shutdown_gen_) power_off();
  });
}

bool Bike::Impl::assist_allowed() const {
  if (!powered_ || vehicle_locked_ || !alive(Node::kMc)) return false;
  bool critical = false;
  motinova::for_each_active_fault(motinova::FaultSource::kMc, mc_faults_,
                                  [&](uint32_t, const motinova::FaultDef* def) {
                                    if (!def || def->severity == motinova::Severity::kCritical) {
                                      critical = true;
                                    }
                                  });
  // A BMS that trips its protection cuts the output; its alarms alone do not.
  return !critical && (bms_faults_ & 0xFFFF) == 0;
}

void Bike::Impl::handle_mc_command(const AppFrame& f, bool from_obc) {
  if (!alive(Node::kMc)) return;
  auto ack = [this, from_obc] {
    // U26: the MC confirms OBC writes; IOT writes are not acknowledged (verify by read-back).
    if (from_obc) after(reply_latency(), [this] { send_keyword(Node::kMc, 0x713, 0x53); });
  };
  switch (f.function) {
    case 0x30: {  // assist level + headlight
      const auto level = decoded_.raw("assist");
      const uint8_t light = f.data[1];
      if (!level || !valid_assist(*level) || (light != 0xF0 && light != 0xF1)) return;
      assist_ = static_cast<uint8_t>(*level);
      headlight_ = light == 0xF1;
      return;
    }
    case 0x31:  // READY: answer to our OBC handshake (from the OBC, or the IOT standing in, U13)
      if (keyword_ok(f)) {
        obc_ok_ = true;
        set_faults(Node::kMc, kMcObcCheckBit, false);
      }
      return;
    case 0x33:
      after(reply_latency(), [this] { send_mc_settings(); });
      return;
    case 0x34: {
      const auto offset = decoded_.raw("speed_limit_offset_kmh");
      const auto adjust = decoded_.raw("wheel_adjust_cm");
      const auto mode = decoded_.raw("mode");
      // Out-of-range values are refused as a whole, as a cautious firmware would.
      if (!offset || *offset < -50 || *offset > 0 || !adjust || *adjust < -10 || *adjust > 10 ||
          !mode || *mode < 1 || *mode > 3) {
        return;
      }
      speed_limit_offset_ = static_cast<int>(*offset);
      wheel_adjust_cm_ = static_cast<int>(*adjust);
      mc_mode_ = static_cast<uint8_t>(*mode);
      ack();
      return;
    }
    case 0x35:
      after(reply_latency(), [this] { send_mc_odometer(); });
      return;
    case 0x36:
      if (!keyword_ok(f)) return;
      trip_m_ = trip_riding_s_ = trip_mah_ = trip_wh_ = 0;
      ack();
      return;
    case 0x39:
    case 0x41:
      after(reply_latency(), [this] { send_mc_params2(); });
      return;
    case 0x40:
      ack();
      return;  // working mode (U8): accepted, no visible effect
    case 0x42:
      for (std::size_t i = 0; i < 4; ++i) params2_[i + 1] = f.data[i];
      ack();
      return;
    case 0x43:
      after(reply_latency(), [this] { send_mc_tuning(); });
      return;
    case 0x44:
      std::copy(f.data.begin(), f.data.end(), tuning_.begin());
      ack();
      return;
    default:
      return;
  }
}

void Bike::Impl::handle_lock_command(const AppFrame& f, std::size_t i) {
  const LockSim& l = locks_[i];
  if (!alive(l.node)) return;
  const auto base = static_cast<uint8_t>(0x80 + 0x10 * i);
  if (f.function == base) {
    after(reply_latency(), [this, i] {
      send_device_info(locks_[i].node, broadcast_id(locks_[i].node), 0x12, sc_.lock,
                       "-" + std::to_string(i + 1));
    });
  } else if (f.function == base + 1) {
    after(reply_latency(), [this, i] { send_lock_status(i); });
  } else if ((f.function == base + 2 || f.function == base + 3) && keyword_ok(f)) {
    actuate(i, f.function == base + 2);
  }
}

// §3.8.3: the lock answers a LOCK/UNLOCK by moving through locking/unlocking (status broadcast
// on every change) to locked/unlocked after 300..800 ms, or to lock/unlock failed after a 2 s
// timeout when jammed.
void Bike::Impl::actuate(std::size_t i, bool lock) {
  LockSim& l = locks_[i];
  const LockState target = lock ? LockState::kLocked : LockState::kUnlocked;
  const LockState moving = lock ? LockState::kLocking : LockState::kUnlocking;
  if (l.state == moving) return;  // already on its way
  if (l.state == target) {        // nothing to do: confirm with a status broadcast
    after(reply_latency(), [this, i] { send_lock_status(i); });
    return;
  }
  const uint64_t gen = ++l.generation;
  after(Micros(static_cast<int64_t>(uniform(10'000, 30'000))),
        [this, i, gen, lock, target, moving] {
          LockSim& lk = locks_[i];
          if (gen != lk.generation || !alive(lk.node)) return;
          lk.state = moving;
          lk.moving = true;
          send_lock_status(i);
          const bool jammed = lk.jammed;
          const Micros travel =
              jammed ? ms(2000) : Micros(static_cast<int64_t>(uniform(300'000, 800'000)));
          after(travel, [this, i, gen, lock, target, jammed] {
            LockSim& lk2 = locks_[i];
            if (gen != lk2.generation) return;
            lk2.moving = false;
            if (jammed) {
              lk2.state = lock ? LockState::kLockFailed : LockState::kUnlockFailed;
              set_faults(lk2.node, kLockStallBit, true);
            } else {
              lk2.state = target;
              set_faults(lk2.node, kLockStallBit, false);
            }
            send_lock_status(i);
          });
        });
}

void Bike::Impl::handle(const AppFrame& f) {
  ++stats_.messages_received;
  // 0x763 function 0x70 carries two messages told apart by length (read 0x7000, write
  // "SHUTDOWN" 0x7008), so it is dispatched before the catalogue look-up.
  if (f.can_id == 0x763 && f.function == 0x70) {
    if (!alive(Node::kObc)) return;
    if (f.mode == motinova::Mode::kRead && f.data.empty()) {
      after(reply_latency(), [this] { send_device_info(Node::kObc, 0x730, 0x11, sc_.obc); });
    } else if (f.data.span().size() == 8 &&
               std::equal(f.data.begin(), f.data.end(), std::string_view("SHUTDOWN").begin())) {
      // The OBC confirms and switches itself off; the rest of the bike stays up.
      after(reply_latency(), [this] { send_keyword(Node::kObc, 0x730, 0x14); });
      after(ms(1000), [this] { switched_off_[static_cast<std::size_t>(Node::kObc)] = true; });
    }
    return;
  }

  motinova::decode(f, motinova::Catalogue::standard(), opts_, decoded_);
  if (decoded_.status != motinova::DecodeStatus::kOk) {
    ++stats_.ignored_messages;
    return;
  }
  switch (f.can_id) {
    case 0x712:  // MC -> BMS HANDSHAKE
      if (f.function == 0x30 && keyword_ok(f) && alive(Node::kBms)) {
        after(reply_latency(), [this] { send_keyword(Node::kBms, 0x721, 0x30); });
      }
      return;
    case 0x713:  // MC -> OBC HANDSHAKE
      if (f.function == 0x50 && keyword_ok(f) && alive(Node::kObc)) {
        after(reply_latency(), [this] { send_keyword(Node::kObc, 0x731, 0x31); });
      }
      return;
    case 0x721:  // BMS READY
      if (f.function == 0x30 && keyword_ok(f)) {
        bms_ok_ = true;
        set_faults(Node::kMc, kMcBmsCheckBit, false);
      }
      return;
    case 0x731:
      handle_mc_command(f, true);
      return;
    case 0x761:
      handle_mc_command(f, false);
      return;
    case 0x732:
    case 0x762: {  // BMS block reads (§3.3.9, U16): pairing documented in docs/simulator.md
      if (!alive(Node::kBms)) return;
      switch (f.function) {
        case 0x50:
          after(reply_latency(), [this] { send_bms_status(); });
          break;
        case 0x51:
          after(reply_latency(), [this] {
            send_bms_cells();
            send_device_info(Node::kBms, 0x720, 0x15, sc_.bms);
          });
          break;
        case 0x52:
          after(reply_latency(), [this] { send_fault_word(Node::kBms); });
          break;
        case 0x53:
          after(reply_latency(), [this] { send_bms_nameplate(); });
          break;
        case 0x54:
          after(reply_latency(), [this] {
            send_bms_temps();
            send_pack_stats();
          });
          break;
        default:
          break;
      }
      return;
    }
    case 0x752:  // CDL reads of BMS data: all answered with the pack statistics
      if (alive(Node::kBms)) after(reply_latency(), [this] { send_pack_stats(); });
      return;
    case 0x760:  // IOT broadcasts
      if (!keyword_ok(f)) return;
      if (f.function == 0x10) shutdown_requested(Node::kIot);
      if (f.function == 0x11) vehicle_locked_ = true;
      if (f.function == 0x12) vehicle_locked_ = false;
      return;
    case 0x730:  // OBC SHUTDOWN (power key)
      if (f.function == 0x10 && keyword_ok(f)) shutdown_requested(Node::kObc);
      return;
    case 0x720:  // BMS SHUTDOWN (auto-off)
      if (f.function == 0x13 && keyword_ok(f)) shutdown_requested(Node::kBms);
      return;
    default:
      if (f.can_id >= 0x767 && f.can_id <= 0x76B) {
        handle_lock_command(f, static_cast<std::size_t>(f.can_id - 0x767));
      }
      return;
  }
}

void Bike::Impl::apply(const ScenarioEvent& ev) {
  const auto node_index = static_cast<std::size_t>(ev.node);
  switch (ev.action) {
    case Action::kFault:
      set_faults(ev.node, ev.bits, true);
      break;
    case Action::kClear:
      set_faults(ev.node, ev.bits == 0 ? 0xFFFFFFFF : ev.bits, false);
      break;
    case Action::kJamLock:
      locks_[static_cast<std::size_t>(motinova::lock_index(ev.node))].jammed = true;
      break;
    case Action::kUnjamLock:
      locks_[static_cast<std::size_t>(motinova::lock_index(ev.node))].jammed = false;
      break;
    case Action::kSilenceNode: {
      silent_[node_index] = true;
      const uint64_t gen = ++silence_gen_[node_index];
      if (ev.duration.count() > 0) {
        after(ev.duration, [this, node_index, gen] {
          if (gen == silence_gen_[node_index]) silent_[node_index] = false;
        });
      }
      break;
    }
    case Action::kRestoreNode:
      ++silence_gen_[node_index];
      silent_[node_index] = false;
      break;
    case Action::kCorrupt:
      for (uint32_t k = 0; k < ev.count; ++k) corruptions_.push_back({ev.node, ev.corruption});
      break;
    case Action::kGarbage:
      garbage(ev.count);
      break;
    case Action::kPowerOff:
      // The power key: the OBC announces SHUTDOWN and cuts power ~1 s later (§3.8.2); the
      // reactions run through the bus like every other message.
      send_keyword(Node::kObc, 0x730, 0x10);
      break;
    case Action::kPowerOn:
      power_on();
      break;
    case Action::kBmsAutoOff:
      send_keyword(Node::kBms, 0x720, 0x13);
      break;
    case Action::kLock:
    case Action::kUnlock:
      if (alive(ev.node)) {
        actuate(static_cast<std::size_t>(motinova::lock_index(ev.node)),
                ev.action == Action::kLock);
      }
      break;
    case Action::kPlugCharger:
      charger_a_ = ev.current_a;
      break;
    case Action::kUnplugCharger:
      charger_a_ = 0;
      charge_longest_s_ = std::max(charge_longest_s_, charge_session_s_);
      charge_session_s_ = 0;
      break;
  }
}

double Bike::Impl::profile_speed_kmh(Micros t_rel, double* grade) const {
  for (std::size_t i = 0; i < segment_ends_.size(); ++i) {
    if (t_rel < segment_ends_[i]) {
      *grade = sc_.ride[i].grade_pct;
      return sc_.ride[i].speed_kmh;
    }
  }
  *grade = 0;
  return 0;  // ride over: parked
}

void Bike::Impl::step_physics() {
  const double dt = kPhysicsStepS;
  double grade_pct = 0;
  double target_kmh = profile_speed_kmh(now_ - sc_.start, &grade_pct);
  if (!powered_ || charger_a_ > 0) target_kmh = 0;  // nobody rides a dead or charging bike
  // Riders in the sim never pedal past the assist cut-off (walk assist: 6 km/h).
  target_kmh = std::min(target_kmh, assist_ == 0x05 ? 6.0 : effective_limit_kmh());

  // A little seeded wobble around the target speed (Ornstein-Uhlenbeck, sigma ~0.5 km/h).
  wobble_kmh_ += -wobble_kmh_ * dt / 5.0 + 0.35 * normal() * std::sqrt(dt);
  const double desired_ms =
      target_kmh > 0
          ? std::max(0.0, std::min(target_kmh + wobble_kmh_, effective_limit_kmh())) / 3.6
          : 0.0;
  const double v0 = speed_ms_;
  double v1 = v0 + std::clamp(desired_ms - v0, -kMaxBrake * dt, kMaxAccel * dt);
  if (v1 < 0.05) v1 = desired_ms > 0 ? v1 : 0.0;
  speed_ms_ = v1;

  const double v_avg = (v0 + v1) / 2;
  const double dist = v_avg * dt;
  odo_m_ += dist;
  trip_m_ += dist;
  if (v_avg > 0) {
    odo_riding_s_ += dt;
    trip_riding_s_ += dt;
  }

  // Power at the wheel, split between rider and motor by the assist ratio.
  const double slope = grade_pct / 100.0;
  const double force = kMassKg * kGravity * (kCrr + slope) +
                       0.5 * kAirDensity * kCdA * v_avg * v_avg + kMassKg * (v1 - v0) / dt;
  const double wheel_w = std::max(0.0, force * v_avg);
  double motor_w = 0;
  if (assist_allowed() && v_avg > 0) {
    if (assist_ == 0x05) {
      motor_w = v_avg * 3.6 <= 6.0 ? std::min(wheel_w, 150.0) : 0.0;
    } else if (v_avg * 3.6 <= effective_limit_kmh()) {
      const double r = assist_ratio(assist_);
      motor_w = std::min(kMotorMaxW, wheel_w * r / (1 + r));
    }
  }
  motor_w_ = motor_w;
  const double rider_w = wheel_w - motor_w;
  cadence_ = v_avg > 0.3 ? std::clamp(50 + v_avg * 3.6 * 1.2, 45.0, 95.0) : 0.0;
  torque_ = cadence_ > 0 ? rider_w / (cadence_ * 2 * std::numbers::pi / 60.0) : 0.0;
  motor_rpm_ = motor_w > 0 ? cadence_ * 36.0 : 0.0;  // mid-drive reduction ~1:36

  // Pack: electrical load -> discharge current with IR drop; charger -> CC/CV charge current.
  const double soc = remaining_mah_ / full_mah_ * 100.0;
  const double ocv = cell_ocv(soc) * kSeriesCells;
  double load_w = 0;
  if (powered_) load_w = motor_w / kMotorEfficiency + kStandbyW + (headlight_ ? kHeadlightW : 0);
  double i_dis = 0;
  const double disc = ocv * ocv - 4 * kPackResistance * load_w;
  if (load_w > 0) {
    i_dis = disc > 0 ? (ocv - std::sqrt(disc)) / (2 * kPackResistance) : load_w / ocv;
  }
  double i_chg = 0;
  if (charger_a_ > 0 && soc < 99.95 && (bms_faults_ & 0xFFFF) == 0) {
    const double cell = cell_ocv(soc);
    i_chg = cell < 4.12 ? charger_a_ : charger_a_ * std::clamp((4.2 - cell) / 0.08, 0.05, 1.0);
  }
  current_a_ = i_chg - i_dis;
  pack_v_ = ocv + current_a_ * kPackResistance;
  const double dmah = current_a_ * 1000.0 * dt / 3600.0;
  remaining_mah_ = std::clamp(remaining_mah_ + dmah, 0.0, full_mah_);
  energy_out_wh_ += pack_v_ * i_dis * dt / 3600.0;
  energy_in_wh_ += pack_v_ * i_chg * dt / 3600.0;
  trip_mah_ += i_dis * 1000.0 * dt / 3600.0;
  trip_wh_ += pack_v_ * i_dis * dt / 3600.0;
  if (i_chg > 0) {
    charge_session_s_ += dt;
    charge_total_s_ += dt;
  }
  if (powered_) runtime_s_ += dt;

  // Temperatures: first-order towards ambient, driven by I²R in the pack and motor losses.
  const double amb = sc_.ambient_c;
  batt_temp_ += dt * ((current_a_ * current_a_ * 0.4) / 300.0 - (batt_temp_ - amb) / 1800.0);
  motor_temp_ += dt * ((motor_w * 0.25) / 900.0 - (motor_temp_ - amb) / 600.0);
  pcb_temp_ += dt * ((amb + 3 + i_dis * 1.5) - pcb_temp_) / 300.0;
  mcu_temp_ += dt * ((pcb_temp_ + 2) - mcu_temp_) / 120.0;
  max_temp_ = std::max(max_temp_, batt_temp_);
  min_temp_ = std::min(min_temp_, batt_temp_);
  max_discharge_ma_ = std::max(max_discharge_ma_, i_dis * 1000.0);
  max_charge_ma_ = std::max(max_charge_ma_, i_chg * 1000.0);
}

BikeState Bike::Impl::state() const {
  BikeState s;
  s.powered = powered_;
  s.speed_kmh = speed_ms_ * 3.6;
  s.odo_m = odo_m_;
  s.trip_m = trip_m_;
  s.odo_riding_s = odo_riding_s_;
  s.trip_riding_s = trip_riding_s_;
  s.soc_pct = remaining_mah_ / full_mah_ * 100.0;
  s.remaining_mah = remaining_mah_;
  s.pack_voltage_v = pack_v_;
  s.pack_current_a = current_a_;
  s.motor_power_w = motor_w_;
  s.energy_out_wh = energy_out_wh_;
  s.energy_in_wh = energy_in_wh_;
  s.battery_temp_c = batt_temp_;
  s.motor_temp_c = motor_temp_;
  s.assist = assist_;
  s.headlight = headlight_;
  s.vehicle_locked = vehicle_locked_;
  s.charging = charger_a_ > 0 && current_a_ > 0.01;
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
