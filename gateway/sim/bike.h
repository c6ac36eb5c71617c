// A simulated MOTINOVA V4.6.2 e-bike: MC, BMS, OBC and up to five locks on one CAN bus, driven
// by a Scenario. Used by the VirtualBus (tests, fast replays), the SimTransport (the gateway
// against a bike in accelerated real time), `fleetgw sim` and the candump recorder.
//
// Contract:
//  * Deterministic discrete-event state machine: no clock, no I/O, no threads. The same scenario
//    (same seed) and the same sequence of receive()/advance_to() calls produce exactly the same
//    CAN frames. Time only moves through the `now` arguments (the virtual timeline starts at
//    Scenario::start); `now` must not go backwards (an earlier `now` is treated as the current
//    time).
//  * advance_to(now, emit) runs every internal event due at or before `now`, in time order, and
//    calls emit() for every CAN frame put on the bus; the segments of one application frame are
//    emitted consecutively. During emit(), current_time() is the frame's bus timestamp.
//  * receive() accepts any CAN frame seen on the bus (the gateway's, or anyone's). Frames are
//    reassembled per ID with motinova::Reassembler and decoded with motinova::decode; the nodes'
//    reactions are scheduled a few milliseconds later (never emitted from inside receive()).
//    The bike also hears its own frames (the bus is shared), so e.g. an OBC SHUTDOWN makes the
//    MC answer READY, and a corrupted frame is lost to the simulated nodes as well.
//  * Node behaviour, periods and which read is answered with what: docs/simulator.md.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>

#include "gateway/sim/scenario.h"
#include "motinova/can.h"

namespace fleetgw::sim {

// Lock-state values of lock status 0x1010 byte 5 (best-guess reading U19).
enum class LockState : uint8_t {
  kUnknown = 0,
  kUnlocked = 1,
  kLocked = 2,
  kUnlocking = 3,
  kLocking = 4,
  kUnlockFailed = 5,
  kLockFailed = 6,
};

// Physical truth of the simulation, for tests and diagnostics (the gateway never sees this).
struct BikeState {
  bool powered = true;
  double speed_kmh = 0;
  double odo_m = 0;  // exact, not quantised
  double trip_m = 0;
  double odo_riding_s = 0;  // time with speed > 0
  double trip_riding_s = 0;
  double soc_pct = 0;
  double remaining_mah = 0;
  double pack_voltage_v = 0;  // terminal voltage
  double pack_current_a = 0;  // charge +, discharge -
  double motor_power_w = 0;   // mechanical assist power
  double energy_out_wh = 0;   // electrical energy drawn from the pack
  double energy_in_wh = 0;    // electrical energy put into the pack by the charger
  double battery_temp_c = 0;
  double motor_temp_c = 0;
  uint8_t assist = 0;
  bool headlight = false;
  bool vehicle_locked = false;
  bool charging = false;
  int speed_limit_offset_kmh = 0;
  uint32_t mc_faults = 0;  // normalised fault words
  uint32_t bms_faults = 0;
  uint32_t obc_faults = 0;
  std::array<uint32_t, kSimLocks> lock_faults{};
  std::array<LockState, kSimLocks> lock_states{};
  bool bms_handshake_ok = false;  // MC saw BMS READY
  bool obc_handshake_ok = false;  // MC saw OBC (or IOT) READY
};

struct BikeStats {
  uint64_t messages_sent = 0;        // application frames put on the bus
  uint64_t can_frames_sent = 0;      // CAN frames emitted (segments, garbage)
  uint64_t corrupted_bitflip = 0;    // messages sent with a flipped bit
  uint64_t corrupted_truncated = 0;  // messages sent with missing trailing segments
  uint64_t garbage_frames = 0;       // random CAN frames injected
  uint64_t suppressed = 0;           // messages not sent because the node was silent or off
  uint64_t external_frames = 0;      // CAN frames passed to receive()
  uint64_t messages_received = 0;    // valid application frames heard (own and external)
  uint64_t ignored_messages = 0;     // heard but not for a simulated node / not understood
  uint64_t rx_errors = 0;            // reassembly errors on the bike's own receive path
};

class Bike {
 public:
  using Emit = std::function<void(const motinova::CanFrame&)>;

  explicit Bike(Scenario scenario);
  ~Bike();
  Bike(Bike&&) noexcept;
  Bike& operator=(Bike&&) noexcept;

  // A CAN frame seen on the bus at `now` (e.g. sent by the gateway).
  void receive(const motinova::CanFrame& frame, Micros now);
  // Runs everything due up to `now` and emits the frames it puts on the bus.
  void advance_to(Micros now, const Emit& emit);
  // Time of the next internal event (there always is one while the bike exists).
  Micros next_event() const;
  // Time of the event being processed (during advance_to) or of the last one processed.
  Micros current_time() const;

  // The IOT's ACC output (spec §3.5.1): off removes power from every simulated node, on boots
  // them (MC handshakes). Lets a test harness model the gateway's ACC line.
  void set_acc(bool on, Micros now);

  BikeState state() const;
  const BikeStats& stats() const;
  const Scenario& scenario() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fleetgw::sim
