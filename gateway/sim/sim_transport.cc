#include "gateway/sim/sim_transport.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <asio/post.hpp>

#include "gateway/sim/sim_gnss.h"

namespace fleetgw::sim {

RealtimeDriver::RealtimeDriver(asio::io_context& io, Bike& bike, double acceleration)
    : bike_(bike), acceleration_(acceleration), timer_(io) {
  if (!(acceleration > 0) || !std::isfinite(acceleration)) {
    throw std::invalid_argument("sim: acceleration must be a positive number");
  }
  bike_emit_ = [this](const motinova::CanFrame& frame) {
    if (emit_) emit_(frame, bike_.current_time());
  };
}

RealtimeDriver::~RealtimeDriver() {
  stop();
}

void RealtimeDriver::start(Emit emit) {
  emit_ = std::move(emit);
  real_start_ = std::chrono::steady_clock::now();
  virtual_start_ = bike_.current_time();
  delivered_to_ = virtual_start_;
  running_ = true;
  arm();
}

void RealtimeDriver::stop() {
  running_ = false;
  timer_.cancel();
  armed_for_.reset();
}

void RealtimeDriver::set_batch_window(std::chrono::steady_clock::duration window) {
  window_ = window;
  arm();
}

void RealtimeDriver::set_low_latency(bool on) {
  if (on == low_latency_) return;
  low_latency_ = on;
  arm();
}

void RealtimeDriver::flush() {
  // Lock-step: nothing stamped before virtual_now() is left undelivered; nothing to do.
  if (!running_ || lockstep_) return;
  fire();
}

Micros RealtimeDriver::paced_now() const {
  const auto real = std::chrono::duration_cast<std::chrono::duration<double, std::micro>>(
      std::chrono::steady_clock::now() - real_start_);
  return virtual_start_ + Micros(static_cast<int64_t>(real.count() * acceleration_));
}

Micros RealtimeDriver::virtual_now() const {
  if (!running_ && real_start_ == std::chrono::steady_clock::time_point{}) {
    return bike_.current_time();
  }
  if (!lockstep_) return paced_now();
  if (held_at_) return *held_at_;
  // While an instant is delivered, that instant: the bike schedules its reactions to its own
  // frames (hearing them on the bus) only after the handler returned, so its next event does
  // not yet tell what is still due.
  if (delivering_) return delivered_to_;
  // Short of the next frame not yet delivered (by 1 µs: a frame due at that very instant has
  // not reached the gateway), however late the event loop comes back to the driver.
  return std::max(delivered_to_, std::min(paced_now(), bike_.next_event() - Micros(1)));
}

void RealtimeDriver::hold() {
  if (!lockstep_ || !running_ || held_at_) return;
  held_at_ = virtual_now();
}

void RealtimeDriver::release() {
  if (!held_at_) return;
  const Micros at = *held_at_;
  held_at_.reset();
  // The time the frames spent in flight was no bus time: the clock goes on from where it was
  // held (on an idle machine that is microseconds; under load it is the slip).
  if (paced_now() > at) rebase(at);
  arm();
}

void RealtimeDriver::rebase(Micros bus_now) {
  const auto behind_by = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double, std::micro>(
          static_cast<double>((bus_now - virtual_start_).count()) / acceleration_));
  real_start_ = std::chrono::steady_clock::now() - behind_by;
}

void RealtimeDriver::receive(std::span<const motinova::CanFrame> frames) {
  if (!running_ || frames.empty()) return;
  if (lockstep_) {
    // At the bus time the gateway sent it (held since send()); nothing of the bike's is due
    // before that (virtual_now() stops short of its next event).
    const Micros at = std::max(delivered_to_, virtual_now());
    delivered_to_ = at;
    delivering_ = true;
    bike_.advance_to(at, bike_emit_);
    delivering_ = false;
    if (!running_) return;
    if (on_advanced_) on_advanced_(at);
    for (const auto& frame : frames) bike_.receive(frame, at);
    if (!held_at_) arm();  // held: release() re-arms once the whole batch is in
    return;
  }
  // What the bike sent before these frames reached it goes first (a batch may hold it back):
  // the bike's timeline never runs backwards. More than a step of it is fire()'s work, within
  // its budget; while that leaves the bike behind (until the timer's next turn), frames reach
  // the bike at the time it has reached, so a burst of frames costs no more bus time than one.
  // Called from the event loop (SimTransport posts), so emitting here re-enters nobody.
  if (!behind_ && virtual_now() - delivered_to_ > step()) fire();
  if (!running_) return;
  const Micros at = behind_ ? delivered_to_ : std::max(delivered_to_, virtual_now());
  delivered_to_ = at;
  bike_.advance_to(at, bike_emit_);
  if (!running_) return;  // the handler stopped us
  if (on_advanced_) on_advanced_(at);
  for (const auto& frame : frames) bike_.receive(frame, at);
  arm();  // the reaction may be due before the event the timer waits for
}

void RealtimeDriver::arm() {
  if (!running_) return;
  if (lockstep_ && held_at_) return;  // release() arms
  // Lock-step: the next event at its paced time (at once when that has passed), no window.
  const Micros wait_virtual = bike_.next_event() - (lockstep_ ? paced_now() : virtual_now());
  const auto wait_real = std::chrono::microseconds(static_cast<int64_t>(
      std::max<double>(0, static_cast<double>(wait_virtual.count())) / acceleration_));
  auto at = std::chrono::steady_clock::now() + wait_real;
  // Batching: the next wake-up for the bike's traffic is at least one window after the last
  // delivery; whatever falls due meanwhile waits and goes out together. Not while behind:
  // the next bounded step follows at once (after what the loop has queued meanwhile).
  if (!lockstep_ && !low_latency_ && !behind_ && window_.count() > 0) {
    at = std::max(at, last_delivery_ + window_);
  }
  if (armed_for_ && *armed_for_ == at) return;
  armed_for_ = at;
  timer_.expires_at(at);
  timer_.async_wait([this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
    if (ec || token.expired()) return;
    armed_for_.reset();
    fire();
  });
}

Micros RealtimeDriver::step() const {
  return Micros(std::max<int64_t>(
      1'000, static_cast<int64_t>(static_cast<double>(Micros(kStep).count()) * acceleration_)));
}

void RealtimeDriver::fire() {
  if (!running_) return;
  if (lockstep_) {
    fire_lockstep();
    return;
  }
  const auto started = std::chrono::steady_clock::now();
  last_delivery_ = started;
  // Everything due, in steps, but at most kWorkBudget of real time per wake-up: a machine
  // slower than the acceleration (a sanitizer build at 2000x) falls behind in bounded turns and
  // the event loop runs between them. One unbounded step grew with every turn and starved it.
  const Micros target = virtual_now();
  while (delivered_to_ < target) {
    delivered_to_ = std::min(target, delivered_to_ + step());
    bike_.advance_to(delivered_to_, bike_emit_);
    if (!running_) return;  // the handler stopped us
    if (on_advanced_) on_advanced_(delivered_to_);
    if (std::chrono::steady_clock::now() - started >= kWorkBudget) break;
  }
  behind_ = delivered_to_ < target;
  // The simulation slips: its clock restarts from where the bike has got to, so the gateway
  // (which reads virtual_now() for its own deadlines) and the bike share one timeline and the
  // gap cannot grow. The acceleration is a ceiling, not a promise, on a machine too slow for it.
  if (behind_) rebase(delivered_to_);
  arm();
}

void RealtimeDriver::fire_lockstep() {
  if (held_at_) return;  // the gateway's frames reach the bike first; release() re-arms
  last_delivery_ = std::chrono::steady_clock::now();
  const Micros next = bike_.next_event();
  const Micros ceiling = paced_now();
  if (next <= ceiling) {
    // One bus instant, then the event loop: the gateway handles it (and what it sends reaches
    // the bike at this instant) before the bus moves on.
    delivered_to_ = std::max(delivered_to_, next);
    delivering_ = true;
    bike_.advance_to(delivered_to_, bike_emit_);
    delivering_ = false;
    if (!running_) return;  // the handler stopped us
    if (on_advanced_) on_advanced_(delivered_to_);
    // Behind the ceiling by more than a step (a loaded machine): slip instead of racing to
    // catch up, so the gateway's wall-clock stages (group commit, uplink) see the same pace.
    if (ceiling - delivered_to_ > step()) rebase(delivered_to_ + step());
  }
  arm();
}

SimTransport::SimTransport(asio::io_context& io, Scenario scenario, double acceleration)
    : io_(io),
      bike_(std::move(scenario)),
      driver_(io, bike_, acceleration),
      name_("sim:" + bike_.scenario().name) {}

SimTransport::~SimTransport() {
  on_health_ = nullptr;  // the owner may be half destroyed: no callbacks from the destructor
  stop();
}

void SimTransport::serve_nmea(const std::filesystem::path& link) {
  if (started_) throw std::logic_error("SimTransport::serve_nmea after start");
  gnss_ = std::make_unique<SimGnss>(bike_, link);
  driver_.set_on_advanced([this](Micros t) { gnss_->on_bus_time(t); });
}

void SimTransport::start(FrameHandler on_frame, HealthHandler on_health) {
  if (started_) throw std::logic_error("SimTransport::start called twice");
  started_ = true;
  on_frame_ = std::move(on_frame);
  on_health_ = std::move(on_health);
  health_.state = can::ControllerState::kUp;
  health_.detail = "simulated bus, scenario " + bike_.scenario().name;
  if (on_health_) on_health_(health_);
  if (gnss_) gnss_->on_bus_time(bike_.current_time());  // where the bike stands at the start
  driver_.start([this](const motinova::CanFrame& frame, Micros ts) {
    ++health_.rx_frames;
    if (on_frame_) on_frame_(frame, ts);
  });
}

bool SimTransport::send(const motinova::CanFrame& frame) {
  if (!started_ || stopped_ || frame.len > 8) {
    ++health_.tx_failures;
    return false;
  }
  ++health_.tx_frames;
  // Delivered from the event loop, like a real transmit, so a handler that sends while it is
  // being called never re-enters the bike.
  outgoing_.push_back(frame);
  if (delivery_posted_) return true;
  delivery_posted_ = true;
  driver_.hold();  // lock-step: the bus waits for these frames
  asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
    if (token.expired() || stopped_) return;
    delivery_posted_ = false;
    // What the bike's answers make the gateway send meanwhile waits for the next turn.
    // All at one bus time: they left back to back (RealtimeDriver::receive).
    std::vector<motinova::CanFrame> frames;
    frames.swap(outgoing_);
    driver_.receive(frames);
    if (stopped_) return;
    // What the bike's answers made the gateway send meanwhile is held again by its send().
    if (!delivery_posted_) driver_.release();
  });
  return true;
}

void SimTransport::stop() {
  if (stopped_) return;
  stopped_ = true;
  driver_.stop();
  alive_.reset();
  if (started_) {
    health_.state = can::ControllerState::kDown;
    health_.detail = "stopped";
    if (on_health_) on_health_(health_);
  }
}

}  // namespace fleetgw::sim
