// The simulated bike's inside, shared by the files that implement it (not part of the public
// interface: include gateway/sim/bike.h). One Impl holds every node; nodes interact only
// through frames on the (internal) bus, exactly as the real ones do, so the gateway sees the
// same causal chains (HANDSHAKE -> READY, SHUTDOWN -> READY, UNLOCK -> unlocking -> unlocked).
//
// Contract (of the split, the behaviour is bike.h's):
//  * bike.cc        construction (the periodic schedule), event queue, bus output, state();
//  * bike_messages.cc what each node puts on the bus (message encoders, fault word timing);
//  * bike_behaviour.cc how the nodes react to the bus and to scenario events (handshakes,
//    power, shutdown, MC settings, lock actuation);
//  * ride_physics.*  the physical model, stepped every 100 ms by step_physics().
//  Everything runs on the caller's thread inside advance_to()/receive(); only the seeded
//  generator rng_ provides randomness, so the order of draws is part of the determinism.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <string_view>
#include <vector>

#include "gateway/sim/bike.h"
#include "gateway/sim/ride_physics.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/frame.h"
#include "motinova/reassembler.h"

namespace fleetgw::sim::detail {

using motinova::AppFrame;
using motinova::CanFrame;
using motinova::Node;

constexpr Micros ms(int64_t v) {
  return Micros(v * 1000);
}
inline constexpr Micros kNever = Micros::max();

inline bool valid_assist(int64_t v) {
  return (v >= 0 && v <= 5) || v == 0x22 || v == 0x33;
}

// A physical value rounded into a raw field's range (non-finite values become `lo`).
inline int64_t clamp_raw(double v, int64_t lo, int64_t hi) {
  if (!std::isfinite(v)) return lo;
  return std::clamp<int64_t>(static_cast<int64_t>(std::llround(v)), lo, hi);
}

inline int64_t temp_raw(double c) {
  return clamp_raw(c + 40.0, 0, 255);
}

constexpr uint16_t broadcast_id(Node n) {
  return motinova::make_can_id(n, Node::kBroadcast);
}

// Lock fault bit raised when an actuation times out (0x0040, "perhaps motor stall/jam", U20).
inline constexpr uint32_t kLockStallBit = 0x0040;
// MC fault bits for failed start-up checks (§3.8.1).
inline constexpr uint32_t kMcBmsCheckBit = 0x0400;
inline constexpr uint32_t kMcObcCheckBit = 0x1000;

}  // namespace fleetgw::sim::detail

namespace fleetgw::sim {

class Bike::Impl final : public motinova::FrameSink {
 public:
  explicit Impl(Scenario scenario);

  void receive(const motinova::CanFrame& frame, Micros now) {
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

  Micros next_event() const { return queue_.empty() ? detail::kNever : queue_.front().at; }
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
  void on_frame(const motinova::AppFrame& frame, Micros timestamp) override {
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
    motinova::Node node = motinova::Node::kLock1;
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
  bool alive(motinova::Node n) const {
    const auto i = static_cast<std::size_t>(n);
    if (!powered_ || silent_[i] || switched_off_[i]) return false;
    if (motinova::is_lock(n))
      return locks_[static_cast<std::size_t>(motinova::lock_index(n))].fitted;
    return n == motinova::Node::kMc || n == motinova::Node::kBms || n == motinova::Node::kObc;
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
  void send(motinova::Node src, const motinova::AppFrame& frame);
  void put(const motinova::CanFrame& can) {
    ++stats_.can_frames_sent;
    if (emit_) (*emit_)(can);
    rx_.push(can, now_, *this);
  }
  void garbage(uint32_t count);

  // ---- node messages ----
  void send_mc_status();
  void send_mc_odometer();
  void send_device_info(motinova::Node src, uint16_t can_id, uint8_t function,
                        const DeviceStrings& d, std::string_view serial_suffix = {});
  void send_keyword(motinova::Node src, uint16_t can_id, uint8_t function) {
    send(src, writer(can_id, function).frame());
  }
  void send_mc_settings();
  void send_mc_params2();
  void send_mc_tuning();
  void send_mc_lifetime(bool second);  // 0x715/0xA230 (record 1) or 0xAC10 (record 2)
  void send_bms_status();
  void send_bms_cells();
  void send_bms_nameplate();
  void send_bms_temps();
  void send_pack_stats();
  void send_lock_status(std::size_t i);
  void send_fault_word(motinova::Node n);
  uint32_t& fault_word(motinova::Node n);
  FaultTx& fault_tx(motinova::Node n);
  void fault_tick(motinova::Node n);
  void set_faults(motinova::Node n, uint32_t bits, bool on);

  // ---- behaviour ----
  void boot();
  void handshake_round(uint64_t boot_gen, int attempt);
  void power_on();
  void power_off();
  void shutdown_requested(motinova::Node initiator);
  void handle(const motinova::AppFrame& f);
  void handle_mc_command(const motinova::AppFrame& f, bool from_obc);
  void handle_lock_command(const motinova::AppFrame& f, std::size_t i);
  void actuate(std::size_t i, bool lock);
  void apply(const ScenarioEvent& ev);
  void step_physics();  // one RidePhysics step with the bike's current inputs
  double profile_speed_kmh(Micros t_rel, double* grade) const;
  double effective_limit_kmh() const {
    return std::max(0.0, sc_.speed_limit_kmh + speed_limit_offset_);
  }
  bool assist_allowed() const;
  bool keyword_ok(const motinova::AppFrame& f) const {
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
    motinova::Node node;
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
  // Lifetime records (0xA230/0xAC10): activations per normalised fault bit, and the PCB, motor
  // and MCU temperature extremes (max, min) seen in the running data.
  std::array<uint16_t, 21> mc_fault_counts_{};
  std::array<double, 6> mc_temp_extremes_{-1000, 1000, -1000, 1000, -1000, 1000};

  // rider, drive train and pack (ride_physics.h); the ride profile's segment end times
  RidePhysics ride_;
  std::vector<Micros> segment_ends_;

  // BMS
  std::array<double, kSeriesCells> cell_spread_mv_{};
  uint32_t bms_faults_ = 0;
  FaultTx bms_fault_tx_;

  // OBC
  uint32_t obc_faults_ = 0;
  FaultTx obc_fault_tx_;

  std::array<LockSim, kSimLocks> locks_{};
};

}  // namespace fleetgw::sim
