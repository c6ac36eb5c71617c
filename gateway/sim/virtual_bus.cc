#include "gateway/sim/virtual_bus.h"

#include <algorithm>
#include <stdexcept>

namespace fleetgw::sim {

VirtualBus::VirtualBus(Scenario scenario) : VirtualBus(Bike(std::move(scenario))) {}

VirtualBus::VirtualBus(Bike bike)
    : bike_(std::move(bike)), start_(bike_.scenario().start), now_(bike_.current_time()) {}

VirtualBus::ParticipantId VirtualBus::add(Participant participant) {
  participants_.push_back(std::move(participant));
  return participants_.size() - 1;
}

void VirtualBus::send(const motinova::CanFrame& frame, ParticipantId from) {
  pending_.push_back({frame, from});
}

void VirtualBus::deliver(const motinova::CanFrame& frame, Micros ts, ParticipantId from) {
  ++frames_on_bus_;
  for (ParticipantId id = 0; id < participants_.size(); ++id) {
    if (id != from && participants_[id].on_frame) participants_[id].on_frame(frame, ts);
  }
}

void VirtualBus::flush() {
  // Delivering may make participants send more; keep going until the bus is quiet. Index-based
  // because the vector can grow while we walk it.
  for (std::size_t i = 0; i < pending_.size(); ++i) {
    const Pending p = pending_[i];
    bike_.receive(p.frame, now_);
    deliver(p.frame, now_, p.from);
  }
  pending_.clear();
}

void VirtualBus::run_until(Micros until) {
  const Bike::Emit emit = [this](const motinova::CanFrame& frame) {
    deliver(frame, bike_.current_time(), kExternal);
  };
  Micros last = Micros::min();
  int spins = 0;
  for (;;) {
    flush();
    Micros t = bike_.next_event();
    for (const Participant& p : participants_) {
      if (p.next_event) t = std::min(t, p.next_event());
    }
    if (t > until) break;
    t = std::max(t, now_);  // an overdue participant runs now
    if (t == last) {
      // Legitimate bursts at one instant are short; a participant that never moves past `now`
      // would hang the simulation.
      if (++spins > 100'000) {
        throw std::logic_error("VirtualBus: a participant keeps asking for time " +
                               std::to_string(t.count()) + " without advancing");
      }
    } else {
      spins = 0;
      last = t;
    }
    now_ = t;
    if (bike_.next_event() <= t) bike_.advance_to(t, emit);
    flush();
    for (Participant& p : participants_) {
      if (p.tick && p.next_event && p.next_event() <= now_) {
        p.tick(now_);
        flush();
      }
    }
  }
  now_ = std::max(now_, until);
}

}  // namespace fleetgw::sim
