// How the simulated nodes react: start-up handshakes, power and shutdown, MC commands and
// settings, lock actuation, scenario events, and the inputs of each physics step.

#include <algorithm>
#include <string>
#include <string_view>

#include "gateway/sim/bike_impl.h"
#include "motinova/faults.h"

namespace fleetgw::sim {

using namespace detail;

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
  // Scenario: a firmware that takes no remote writes (reads and READY still work).
  if (sc_.mc_ignores_writes && f.mode == motinova::Mode::kWrite) {
    ++stats_.ignored_messages;
    return;
  }
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
      ride_.trip_m = ride_.trip_riding_s = ride_.trip_mah = ride_.trip_wh = 0;
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

  // 0x761 read 0x4100: the other reading of the IOT's parameter-block read (spec 3.5.2, "0x4100
  // also possible"), not in the catalogue on 0x761; answered like the OBC's 0x731 0x4100.
  if (f.can_id == 0x761 && f.function == 0x41 && f.mode == motinova::Mode::kRead &&
      f.data.empty()) {
    if (alive(Node::kMc)) after(reply_latency(), [this] { send_mc_params2(); });
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
    case 0x751:  // CDL (or the gateway's diagnostics) reads of the MC lifetime records
      if (!alive(Node::kMc) || f.mode != motinova::Mode::kRead) return;
      if (f.function == 0x12 || f.function == 0x19) {
        const bool second = f.function == 0x19;
        after(reply_latency(), [this, second] { send_mc_lifetime(second); });
      }
      return;
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
      ride_.charger_a = ev.current_a;
      break;
    case Action::kUnplugCharger:
      ride_.charger_a = 0;
      ride_.charge_longest_s = std::max(ride_.charge_longest_s, ride_.charge_session_s);
      ride_.charge_session_s = 0;
      break;
    case Action::kSwapBattery:
      // The model info (0x720/0x15) and the status blocks read the scenario's values, so the
      // next answers come from the new pack.
      sc_.bms.serial = ev.serial;
      if (ev.soh_pct) sc_.soh_pct = *ev.soh_pct;
      if (ev.cycles) sc_.cycles = *ev.cycles;
      if (ev.soc_pct) ride_.remaining_mah = *ev.soc_pct / 100 * ride_.full_mah;
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
  RideInputs in;
  in.profile_kmh = profile_speed_kmh(now_ - sc_.start, &in.grade_pct);
  in.limit_kmh = effective_limit_kmh();
  in.assist = assist_;
  in.assist_allowed = assist_allowed();
  in.powered = powered_;
  in.headlight = headlight_;
  in.bms_protection_tripped = (bms_faults_ & 0xFFFF) != 0;
  in.ambient_c = sc_.ambient_c;
  in.noise = normal();
  ride_.step(in);
}

}  // namespace fleetgw::sim
