#include "gateway/domain/alarm_tracker.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "gateway/domain/alarm_payload.h"
#include "motinova/can.h"

namespace fleetgw::domain {
namespace {

constexpr int kUnlocked = 1;
constexpr int kLocked = 2;
constexpr int kUnlocking = 3;
constexpr int kLocking = 4;
constexpr int kLockFailed = 6;

// Why a swap was armed when the gateway restarted: it could not watch the battery lock meanwhile.
constexpr std::string_view kArmedByRestart = "changed while the gateway was off";

// A serial from the bus is untrusted: it ends up in the store, a log and a protobuf string
// (which must be UTF-8). Printable ASCII only, bounded.
std::string printable_serial(std::string_view s) {
  std::string out(s.substr(0, 32));
  for (char& c : out) {
    if (c < 0x20 || c > 0x7E) c = '?';
  }
  return out;
}

std::string format(const char* fmt, double a, double b = 0) {
  std::array<char, 160> buf{};
  std::snprintf(buf.data(), buf.size(), fmt, a, b);
  return buf.data();
}

}  // namespace

void AlarmConfig::validate() const {
  auto bad = [](const std::string& key, const std::string& why) {
    throw std::invalid_argument("alarms." + key + ": " + why);
  };
  if (!(movement_speed_kmh > 0 && movement_speed_kmh <= 30)) {
    bad("movement_speed_kmh", "must be in (0, 30]");
  }
  if (!(movement_rpm > 0 && movement_rpm <= 1000)) bad("movement_rpm", "must be in (0, 1000]");
  if (movement_debounce < Micros(0) || movement_debounce > std::chrono::seconds(60)) {
    bad("movement_debounce_ms", "must be in 0..60000");
  }
  if (movement_clear < std::chrono::seconds(1) || movement_clear > std::chrono::hours(1)) {
    bad("movement_clear_s", "must be in 1..3600");
  }
  if (battery_silent < std::chrono::seconds(1) || battery_silent > std::chrono::hours(1)) {
    bad("battery_silent_ms", "must be in 1000..3600000");
  }
  if (!(low_battery_hysteresis_pct >= 0 && low_battery_hysteresis_pct <= 50)) {
    bad("low_battery_hysteresis_pct", "must be in 0..50");
  }
  for (std::size_t i = 0; i < low_battery_pct.size(); ++i) {
    const int t = low_battery_pct[i];
    const std::string key = "low_battery_pct[" + std::to_string(i) + "]";
    if (t < 1 || t > 99) bad(key, "threshold " + std::to_string(t) + " outside 1..99");
    if (i > 0 && t >= low_battery_pct[i - 1]) bad(key, "thresholds must be strictly descending");
  }
}

AlarmTracker::AlarmTracker(AlarmConfig config, DomainSink& sink)
    : config_(std::move(config)),
      sink_(sink),
      low_fired_(config_.low_battery_pct.size(), false),
      low_emitted_(config_.low_battery_pct.size(), false) {
  config_.validate();
}

bool AlarmTracker::active() const {
  if (movement_.active || removed_.active) return true;
  return std::any_of(locks_.begin(), locks_.end(),
                     [](const Lock& l) { return l.forced.active || l.tamper.active; });
}

std::vector<std::string_view> AlarmTracker::active_kinds() const {
  std::vector<std::string_view> out;
  if (movement_.active) out.emplace_back("unauthorised_movement");
  if (std::any_of(locks_.begin(), locks_.end(), [](const Lock& l) { return l.forced.active; })) {
    out.emplace_back("lock_forced");
  }
  if (std::any_of(locks_.begin(), locks_.end(), [](const Lock& l) { return l.tamper.active; })) {
    out.emplace_back("lock_tamper");
  }
  if (std::find(low_emitted_.begin(), low_emitted_.end(), true) != low_emitted_.end()) {
    out.emplace_back("low_battery");
  }
  if (removed_.active) out.emplace_back("battery_removed");
  return out;
}

bool AlarmTracker::locked() const {
  if (vehicle_locked_) return true;
  for (std::size_t i = 0; i < locks_.size(); ++i) {
    if (locks_[i].state != kLocked) continue;
    const auto& kinds = config_.frame_lock_kinds;
    if (std::find(kinds.begin(), kinds.end(), config_.lock_kinds[i]) != kinds.end()) return true;
  }
  return false;
}

void AlarmTracker::expect_command(motinova::Node lock, Micros now) {
  for (std::size_t i = 0; i < locks_.size(); ++i) {
    if (lock == motinova::Node::kBroadcast ||
        (motinova::is_lock(lock) && static_cast<int>(i) == motinova::lock_index(lock))) {
      locks_[i].commanded_until = now + config_.command_window;
    }
  }
}

void AlarmTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (!config_.enabled || msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return;
  switch (classify(msg)) {
    case BusEvent::kVehicleLock:
      vehicle_locked_ = true;
      expect_command(motinova::Node::kBroadcast, now);
      return;
    case BusEvent::kVehicleUnlock:
      vehicle_locked_ = false;
      expect_command(motinova::Node::kBroadcast, now);
      return;
    case BusEvent::kShutdown:
      after_shutdown_ = true;
      return;
    default:
      break;
  }
  const std::string_view name = msg.desc->name;
  const motinova::Node src = msg.desc->source();
  if ((name == "lock" || name == "unlock") && motinova::is_lock(msg.desc->target())) {
    // The IOT's own LOCK/UNLOCK write to one lock (the gateway is the IOT): a command.
    expect_command(msg.desc->target(), now);
    return;
  }
  if (name == "mc_status") {
    on_mc_status(msg, now);
  } else if (motinova::is_lock(src) && name == "lock_status") {
    if (const auto s = msg.raw("state")) {
      on_lock_status(static_cast<std::size_t>(motinova::lock_index(src)), static_cast<int>(*s),
                     now);
    }
  } else if (motinova::is_lock(src) && msg.desc->kind == motinova::MessageKind::kFaultWord) {
    if (const auto w = msg.raw("raw")) {
      on_lock_faults(static_cast<std::size_t>(motinova::lock_index(src)),
                     static_cast<uint32_t>(*w) & 0xFFFFu, now);
    }
  } else if (src == motinova::Node::kBms && name == "bms_status") {
    bms_heard_ = now;
    after_shutdown_ = false;
    update(soh_, msg, "soh_pct", now);
    update(cycles_, msg, "cycles", now);
    // The first status after a new serial is the new pack's: the swap alarm carries its SOH.
    if (pending_swap_) raise_swap(now);
    if (removed_.active) {
      removed_.active = false;
      emit(record("battery_removed", storage::AlarmTransition::kCleared, now, removed_.first));
    }
    if (const auto soc = msg.number("soc_pct")) {
      soc_ = Reading{*soc, now};
      on_soc(*soc, now);
    }
  } else if (src == motinova::Node::kBms && name == "device_info") {
    if (const auto serial = msg.text("serial"); !serial.empty()) {
      on_bms_serial(std::string(serial), now);
    }
  }
}

void AlarmTracker::on_mc_status(const motinova::DecodedMessage& msg, Micros now) {
  update(speed_, msg, "speed_kmh", now);
  update(rpm_, msg, "motor_rpm", now);
  const bool evidence =
      locked() && ((speed_ && speed_->at == now && speed_->value > config_.movement_speed_kmh) ||
                   (rpm_ && rpm_->at == now && rpm_->value > config_.movement_rpm));
  if (!evidence) {
    evidence_since_.reset();  // a twitch shorter than the debounce is forgotten
    return;
  }
  if (!evidence_since_) {
    evidence_since_ = now;
    if (!movement_.active) max_speed_kmh_ = 0;
  }
  last_evidence_ = now;
  if (speed_) max_speed_kmh_ = std::max(max_speed_kmh_, speed_->value);
  if (!movement_.active && now - *evidence_since_ >= config_.movement_debounce) {
    movement_ = Episode{true, *evidence_since_};
    ++raised_total_;
    storage::AlarmRow rec =
        record("unauthorised_movement", storage::AlarmTransition::kRaised, now, movement_.first);
    rec.detail = format("wheel %.1f km/h, motor %.0f rpm while locked",
                        speed_ ? speed_->value : 0.0, rpm_ ? rpm_->value : 0.0);
    emit(std::move(rec));
  }
}

void AlarmTracker::on_lock_status(std::size_t index, int state, Micros now) {
  Lock& l = locks_.at(index);
  const std::optional<int> before = std::exchange(l.state, state);
  if (config_.lock_kinds[index] == "battery") on_battery_lock(state);
  const std::string lock_name =
      "lock" + std::to_string(index + 1) + " (" + config_.lock_kinds[index] + ")";
  if (l.forced.active && state == kLocked) {
    l.forced.active = false;
    storage::AlarmRow rec =
        record("lock_forced", storage::AlarmTransition::kCleared, now, l.forced.first);
    rec.lock_node = static_cast<int>(motinova::lock_node(static_cast<int>(index)));
    rec.detail = lock_name + " locked again";
    emit(std::move(rec));
    return;
  }
  const bool was_closed =
      before && (*before == kLocked || *before == kLocking || *before == kLockFailed);
  const bool opening = state == kUnlocked || state == kUnlocking;
  if (!was_closed || !opening || l.forced.active || now <= l.commanded_until) return;
  l.forced = Episode{true, now};
  ++raised_total_;
  storage::AlarmRow rec = record("lock_forced", storage::AlarmTransition::kRaised, now, now);
  rec.lock_node = static_cast<int>(motinova::lock_node(static_cast<int>(index)));
  rec.detail = lock_name + " opened without a command";
  emit(std::move(rec));
}

void AlarmTracker::on_lock_faults(std::size_t index, uint32_t bits, Micros now) {
  Lock& l = locks_.at(index);
  if ((bits != 0) == l.tamper.active) return;
  const auto t = bits != 0 ? storage::AlarmTransition::kRaised : storage::AlarmTransition::kCleared;
  if (bits != 0) {
    l.tamper = Episode{true, now};
    ++raised_total_;
  } else {
    l.tamper.active = false;
  }
  storage::AlarmRow rec = record("lock_tamper", t, now, l.tamper.first);
  rec.lock_node = static_cast<int>(motinova::lock_node(static_cast<int>(index)));
  rec.lock_fault_bits = bits;
  rec.detail = "lock" + std::to_string(index + 1) + " (" + config_.lock_kinds[index] + ") ";
  if (bits != 0) {
    std::array<char, 16> hex{};
    std::snprintf(hex.data(), hex.size(), "%04x", bits);
    rec.detail += std::string("reports fault bits 0x") + hex.data();
  } else {
    rec.detail += "fault bits clear";
  }
  emit(std::move(rec));
}

void AlarmTracker::on_soc(double soc, Micros now) {
  const auto& th = config_.low_battery_pct;
  std::optional<std::size_t> lowest;
  for (std::size_t i = 0; i < th.size(); ++i) {
    if (low_fired_[i]) {
      if (soc >= th[i] + config_.low_battery_hysteresis_pct) {
        low_fired_[i] = false;
        const bool emitted = low_emitted_[i];
        low_emitted_[i] = false;
        if (emitted) {
          storage::AlarmRow rec =
              record("low_battery", storage::AlarmTransition::kCleared, now, now);
          rec.threshold_pct = th[i];
          rec.detail = format("SOC %.0f %% back above %.0f %%", soc, th[i]);
          emit(std::move(rec));
        }
      }
    } else if (soc <= th[i]) {
      low_fired_[i] = true;
      lowest = i;  // descending thresholds: the last match is the lowest
    }
  }
  if (!lowest) return;
  low_emitted_[*lowest] = true;
  ++raised_total_;
  storage::AlarmRow rec = record("low_battery", storage::AlarmTransition::kRaised, now, now);
  rec.threshold_pct = th[*lowest];
  rec.detail = format("SOC %.0f %% at or below %.0f %%", soc, th[*lowest]);
  emit(std::move(rec));
}

void AlarmTracker::restore_bms_serial(std::string serial) {
  serial = printable_serial(serial);
  if (serial.empty()) return;
  bms_serial_ = std::move(serial);
  swap_armed_by_ = std::string(kArmedByRestart);
}

void AlarmTracker::on_battery_lock(int state) {
  battery_lock_state_ = state;
  // Opening the battery lock is the only way to take the pack out: the next serial decides.
  if (state == kUnlocked || state == kUnlocking) swap_armed_by_ = "battery lock opened";
}

void AlarmTracker::remember_serial(std::string serial) {
  bms_serial_ = serial;
  sink_.batch().meta.emplace_back(std::string(kBmsSerialMetaKey), std::move(serial));
}

void AlarmTracker::on_bms_serial(std::string serial, Micros now) {
  serial = printable_serial(serial);
  if (serial.empty()) return;
  if (bms_serial_.empty()) {  // the first pack this store knows: nothing to compare with
    swap_armed_by_.reset();
    remember_serial(std::move(serial));
    return;
  }
  if (serial == bms_serial_) {
    // The same pack: a restart's doubt is settled at once, a lock opening once it is closed
    // again (the pack may still be swapped while the lock is open).
    if (swap_armed_by_ && (*swap_armed_by_ == kArmedByRestart || battery_lock_state_ == kLocked)) {
      swap_armed_by_.reset();
    }
    return;
  }
  if (!swap_armed_by_ && battery_lock_state_) {
    // A battery lock is fitted and stayed closed: no swap to report (workshop data, a BMS
    // board replaced); the new serial becomes the reference.
    remember_serial(std::move(serial));
    return;
  }
  pending_swap_ = PendingSwap{bms_serial_, serial,
                              swap_armed_by_.value_or("no battery lock heard on this bike"), now};
  swap_armed_by_.reset();
  remember_serial(std::move(serial));
}

void AlarmTracker::raise_swap(Micros now) {
  const PendingSwap p = std::move(*pending_swap_);
  pending_swap_.reset();
  ++raised_total_;
  storage::AlarmRow rec =
      record("battery_swapped", storage::AlarmTransition::kRaised, now, p.at);
  rec.old_bms_serial = p.old_serial;
  rec.new_bms_serial = p.new_serial;
  rec.detail = "battery " + p.old_serial + " replaced by " + p.new_serial + " (" + p.why + ")";
  emit(std::move(rec));
}

void AlarmTracker::tick(Micros now) {
  if (!config_.enabled) return;
  if (pending_swap_ && now - pending_swap_->at >= kSwapStatusWait) raise_swap(now);
  if (movement_.active && now - last_evidence_ >= config_.movement_clear) {
    movement_.active = false;
    evidence_since_.reset();
    storage::AlarmRow rec =
        record("unauthorised_movement", storage::AlarmTransition::kCleared, now, movement_.first);
    // Evidence stops either because the bike stood still or because it was unlocked (riding on
    // is then authorised): the detail says which, so a cleared alarm at speed is not a riddle.
    rec.detail = format(
        locked() ? "no movement for %.0f s" : "unlocked; no movement while locked for %.0f s",
        static_cast<double>(config_.movement_clear.count()) / 1e6);
    emit(std::move(rec));
  }
  const bool still = !evidence_since_ && !movement_.active;
  if (bms_heard_ && !removed_.active && !after_shutdown_ && still && locked() &&
      now - *bms_heard_ >= config_.battery_silent) {
    removed_ = Episode{true, *bms_heard_};
    ++raised_total_;
    storage::AlarmRow rec =
        record("battery_removed", storage::AlarmTransition::kRaised, now, removed_.first);
    rec.detail = format("BMS silent for %.1f s while parked",
                        static_cast<double>((now - *bms_heard_).count()) / 1e6);
    emit(std::move(rec));
  }
}

storage::AlarmRow AlarmTracker::record(std::string_view kind, storage::AlarmTransition t,
                                          Micros now, Micros first) const {
  storage::AlarmRow rec;
  rec.ts_us = now.count();
  rec.first_evidence_us = first.count();
  rec.kind = std::string(kind);
  rec.transition = t;
  const Micros age = std::chrono::seconds(5);
  rec.speed_kmh = fresh(speed_, now, age);
  rec.motor_rpm = fresh(rpm_, now, age);
  if (kind == "unauthorised_movement") rec.max_speed_kmh = max_speed_kmh_;
  rec.soc_pct = fresh(soc_, now, age);
  if (kind == "battery_removed" && soc_) rec.soc_pct = soc_->value;  // the last one heard
  return rec;
}

void AlarmTracker::emit(storage::AlarmRow rec) {
  AlarmExtras extras;
  if (rec.lock_node) {
    const int index = motinova::lock_index(static_cast<motinova::Node>(*rec.lock_node));
    if (index >= 0 && index < 5)
      extras.lock_kind = config_.lock_kinds[static_cast<std::size_t>(index)];
  }
  if (rec.kind == "battery_swapped") {
    // Only what the BMS said since the new serial was read: the new pack's, not the old one's.
    const Micros since(rec.first_evidence_us);
    if (soh_ && soh_->at >= since) extras.soh_pct = soh_->value;
    if (cycles_ && cycles_->at >= since) extras.cycles = cycles_->value;
  }
  storage::Bytes payload = alarm_payload(rec, extras);
  sink_.batch().alarms.push_back({std::move(rec), std::move(payload)});
}

}  // namespace fleetgw::domain
