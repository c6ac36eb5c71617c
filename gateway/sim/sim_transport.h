// The simulated bike in (accelerated) real time on an asio::io_context.
//
//  * RealtimeDriver paces a Bike against the steady clock: virtual time = virtual start +
//    elapsed real time × acceleration. It is what `fleetgw sim` uses to put the bike on a real
//    (UDP / SocketCAN) bus.
//  * SimTransport is a fleetgw::can::PacedTransport whose "bus" is a simulated Bike in the same
//    process: frames the gateway send()s go to Bike::receive, frames the bike emits reach the
//    gateway's handler stamped with their virtual time (Micros on the scenario's timeline, which
//    starts at Scenario::start). virtual_now() is the clock a gateway runtime should use when it
//    runs against this transport with acceleration != 1.
//
// Contract (both): single-threaded, everything on the io_context's thread; handlers never run
// after stop() or destruction. The Bike itself stays deterministic; only the pacing is real.
//
// Coalescing: every wake-up delivers ALL frames due by then (each with its own bus timestamp).
// With a batch window (set_batch_window, real time), the driver wakes at most once per window
// for the bike's traffic, like a CAN controller that interrupts per batch: frames reach the
// handler up to one window late but in order and correctly stamped. flush() delivers what is
// due at once (the gateway calls it before acting on its own deadlines, so it never acts on a
// stale view of the bus) and restarts the window; set_low_latency(true) suspends batching
// (a command waits for the lock's answer). Window 0 (the default): one wake-up per bike event.
//
// Lock-step (set_lockstep(true), `[sim] lockstep = true`): the bus's virtual time advances with
// what has been delivered and processed, never with the wall clock alone, so a loaded machine
// slows the ride down but never shows the gateway a bus that "fell behind":
//  * virtual_now() never passes the bike's next undelivered event: every frame stamped before
//    the time the gateway reads has reached its handler;
//  * a frame the gateway send()s reaches the bike at the bus time it was sent (the clock is held
//    while it is in flight), so the bike's answer is as late in bus time as on an idle machine;
//  * one bus instant per wake-up, then the event loop runs (the gateway reacts to every instant
//    before the next one); batch windows and flush() have nothing to do;
//  * the acceleration is a ceiling: a machine slower than it slips (the ride takes longer in
//    wall time, by at most one step of catch-up) with the same frames at the same bus times.
// Intended for tests and measurements asserting bus-time behaviour; the wall-clock pacing stays
// the default (fewer wake-ups at speed 1).
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>

#include "gateway/can/paced_transport.h"
#include "gateway/sim/bike.h"

namespace fleetgw::sim {

class SimGnss;  // gateway/sim/sim_gnss.h

class RealtimeDriver {
 public:
  using Emit = std::function<void(const motinova::CanFrame&, Micros timestamp)>;

  // `bike` must outlive the driver. acceleration > 0 (1 = real time).
  RealtimeDriver(asio::io_context& io, Bike& bike, double acceleration);
  ~RealtimeDriver();
  RealtimeDriver(const RealtimeDriver&) = delete;
  RealtimeDriver& operator=(const RealtimeDriver&) = delete;

  // Anchors the bike's current time to "now" and starts emitting.
  void start(Emit emit);
  void stop();
  void set_batch_window(std::chrono::steady_clock::duration window);
  void set_low_latency(bool on);
  // Delivers the frames due by virtual_now() (within one work budget) and re-arms.
  void flush();
  // A frame from the outside bus, delivered to the bike at virtual_now().
  void receive(const motinova::CanFrame& frame) { receive(std::span(&frame, 1)); }
  // Frames sent together (back to back, e.g. the segments of one message), delivered to the
  // bike at ONE bus time: on a real bus they are microseconds apart, so the bike's reassembler
  // (gap_timeout 100 ms of bus time) never sees a gap between them. Delivered one by one at
  // virtual_now(), a stall of 1 ms of wall time between two of them was 100 ms of bus time at
  // x100, and a loaded machine's bike dropped the gateway's two-segment requests unanswered.
  void receive(std::span<const motinova::CanFrame> frames);
  Micros virtual_now() const;
  bool running() const { return running_; }
  // Lock-step pacing (see the top of this file); before start().
  void set_lockstep(bool on) { lockstep_ = on; }
  bool lockstep() const { return lockstep_; }
  // Lock-step: frames from the gateway are on their way to the bike (posted): virtual time
  // stands still until release(), which the delivery calls after its receive()s. No-ops
  // otherwise.
  void hold();
  void release();
  // Called after each step the bike has run, with the bus time it has reached (SimGnss).
  void set_on_advanced(std::function<void(Micros)> hook) { on_advanced_ = std::move(hook); }

 private:
  // One wake-up delivers what is due in steps of kStep of real time's worth of bus time, and
  // yields to the event loop once it has worked kWorkBudget.
  static constexpr std::chrono::milliseconds kStep{10};
  static constexpr std::chrono::milliseconds kWorkBudget{20};

  void arm();
  void fire();
  void fire_lockstep();
  Micros step() const;  // kStep of real time, in bus time
  // virtual start + elapsed real time × acceleration: the wall clock's bus time (lock-step: the
  // ceiling).
  Micros paced_now() const;
  // Restarts the wall clock's bus time at `bus_now` (the simulation slips).
  void rebase(Micros bus_now);

  Bike& bike_;
  double acceleration_;
  asio::steady_timer timer_;
  std::chrono::steady_clock::duration window_{};
  bool low_latency_ = false;
  bool behind_ = false;     // the last wake-up stopped short of virtual_now()
  Micros delivered_to_{0};  // bus time up to which the bike has run
  std::chrono::steady_clock::time_point last_delivery_{};
  std::optional<std::chrono::steady_clock::time_point> armed_for_;
  Emit emit_;
  Bike::Emit bike_emit_;
  std::function<void(Micros)> on_advanced_;
  std::chrono::steady_clock::time_point real_start_{};
  Micros virtual_start_{0};
  bool running_ = false;
  bool lockstep_ = false;
  std::optional<Micros> held_at_;  // lock-step: the bus time a gateway frame was sent at
  bool delivering_ = false;        // lock-step: inside the bike's advance_to (an instant)
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

class SimTransport final : public can::PacedTransport {
 public:
  SimTransport(asio::io_context& io, Scenario scenario, double acceleration = 1.0);
  ~SimTransport() override;

  void start(FrameHandler on_frame, HealthHandler on_health) override;
  bool send(const motinova::CanFrame& frame) override;
  void stop() override;
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return name_; }

  Micros virtual_now() const override { return driver_.virtual_now(); }
  // See RealtimeDriver (coalescing).
  void set_batch_window(std::chrono::steady_clock::duration w) override {
    driver_.set_batch_window(w);
  }
  void set_low_latency(bool on) override { driver_.set_low_latency(on); }
  void flush() override { driver_.flush(); }
  // Lock-step pacing (RealtimeDriver above); before start().
  void set_lockstep(bool on) { driver_.set_lockstep(on); }
  bool lockstep() const { return driver_.lockstep(); }
  Bike& bike() { return bike_; }
  const Bike& bike() const { return bike_; }
  // Serves the scenario's route as NMEA on a pty linked at `link` (see SimGnss); before start().
  void serve_nmea(const std::filesystem::path& link);
  const SimGnss* gnss() const { return gnss_.get(); }

 private:
  asio::io_context& io_;
  Bike bike_;
  RealtimeDriver driver_;
  std::string name_;
  std::unique_ptr<SimGnss> gnss_;
  can::BusHealth health_;
  FrameHandler on_frame_;
  HealthHandler on_health_;
  bool started_ = false;
  bool stopped_ = false;
  // Frames sent to the bike, delivered by one posted handler per turn of the event loop: one
  // handler per frame let a bike that answers every frame grow the loop's queue without bound
  // (a machine slower than the acceleration never got back to its timers).
  std::vector<motinova::CanFrame> outgoing_;
  bool delivery_posted_ = false;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

}  // namespace fleetgw::sim
