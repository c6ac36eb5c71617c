// A lockstep CAN bus on a virtual timeline: the simulated Bike plus any number of other bus
// participants (the gateway's node logic, recorders, test probes). run_until(T) jumps from event
// to event without sleeping, so a 30-minute ride runs in a fraction of a second.
//
// Contract:
//  * Single-threaded and deterministic: participants are served in registration order; at equal
//    times the bike runs first, then frames sent by participants are delivered, then due
//    participants are ticked.
//  * Every frame on the bus reaches every participant except its sender, with the virtual time
//    it was put on the bus; the bike's frames carry Bike::current_time().
//  * send() may be called at any time, including from inside on_frame() or tick(): the frame is
//    queued and delivered (to the bike and the other participants) at the current virtual time,
//    after the callback returns. Callbacks therefore never re-enter each other.
//  * A participant's tick(now) is called when now >= its next_event(); a participant that keeps
//    asking for the same instant without doing anything is a programming error and makes
//    run_until() throw std::logic_error (instead of spinning forever).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "gateway/sim/bike.h"
#include "motinova/can.h"

namespace fleetgw::sim {

class VirtualBus {
 public:
  using FrameHandler = std::function<void(const motinova::CanFrame&, Micros timestamp)>;
  using ParticipantId = std::size_t;
  static constexpr ParticipantId kExternal = static_cast<ParticipantId>(-1);

  struct Participant {
    std::string name;
    FrameHandler on_frame;                 // every frame on the bus not sent by this participant
    std::function<void(Micros now)> tick;  // optional: timed work (polling, own broadcasts)
    std::function<Micros()> next_event;  // optional: when tick() wants to run; Micros::max() = idle
  };

  explicit VirtualBus(Scenario scenario);
  explicit VirtualBus(Bike bike);

  ParticipantId add(Participant participant);

  // Puts a frame on the bus at now() on behalf of `from` (kExternal: not a registered participant).
  void send(const motinova::CanFrame& frame, ParticipantId from = kExternal);

  // Runs every bike event, delivery and participant tick due up to `until`; afterwards now() ==
  // until (unless until < now()).
  void run_until(Micros until);
  void run_for(Micros duration) { run_until(now_ + duration); }

  Micros now() const { return now_; }
  Micros start() const { return start_; }
  Bike& bike() { return bike_; }
  const Bike& bike() const { return bike_; }
  uint64_t frames_on_bus() const { return frames_on_bus_; }

 private:
  struct Pending {
    motinova::CanFrame frame;
    ParticipantId from;
  };
  void deliver(const motinova::CanFrame& frame, Micros ts, ParticipantId from);
  void flush();

  Bike bike_;
  std::vector<Participant> participants_;
  std::vector<Pending> pending_;
  Micros start_;
  Micros now_;
  uint64_t frames_on_bus_ = 0;
};

}  // namespace fleetgw::sim
