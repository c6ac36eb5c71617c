// ParkedMode: parked (locked and still) or riding, the switch behind the gateway's parked rates
// (docs/data-model.md "Parked mode"): while parked the poller reads its slow blocks and the
// uplink sends telemetry batches at the [parked] rates; the first sign of movement, an unlock or
// an alarm switches back at once.
//
// Contract:
//  * Clock-free and single-threaded; update(view, now) with the trackers' current view after
//    every batch of messages and every tick; `now` never goes backwards. It returns true when
//    the mode changed (the owner then applies the rates).
//  * Parked: `enabled`, the vehicle locked (AlarmTracker::locked()), no movement (wheel at or
//    below still_kmh, no movement evidence) and no alarm active, all without interruption for
//    `settle`. Riding: anything else, from the first update that sees it (no debounce on the
//    way out). parked() is nullopt until the first update; next_event() is when a still, locked
//    bike becomes parked (Micros::max() otherwise), so the owner needs no periodic tick for it.
//  * ParkedController is the StateStage's listener around it (state_stage.h): added to the
//    GatewayCore after the Recorder, it evaluates at every listener tick (50 ms of bus time while
//    frames flow, 1 s on a silent bus) from the trackers and the live state, sets the poller's
//    parked period on a change and calls `on_change` (the uplink's rates, the retained state).
//    The trackers and the core must outlive it.
#pragma once

#include <chrono>
#include <functional>
#include <optional>

#include "gateway/domain/domain_trackers.h"
#include "gateway/runtime/gateway_core.h"
#include "motinova/can.h"

namespace fleetgw::runtime {

using motinova::Micros;

struct ParkedConfig {
  bool enabled = true;
  Micros settle = std::chrono::seconds(30);  // parked.settle_s
  double still_kmh = 0.5;                    // the ride tracker's standstill
  // Poll entries of >= Poller::kSlowEntryPeriod wait at least this long while parked...
  Micros poll_period = std::chrono::minutes(5);  // parked.poll_interval_ms
  // ... and the faster stale-rule reads at least this long.
  Micros stale_poll_period = std::chrono::milliseconds(1900);  // parked.stale_poll_ms
};

struct ParkedView {
  bool locked = false;
  bool moving = false;  // wheel above still_kmh, or movement evidence while locked
  bool alarm = false;   // an alarm other than low battery is active
};

class ParkedMode {
 public:
  explicit ParkedMode(ParkedConfig config) : config_(config) {}

  bool update(const ParkedView& view, Micros now);
  std::optional<bool> parked() const { return parked_; }
  Micros next_event() const;
  const ParkedConfig& config() const { return config_; }

 private:
  ParkedConfig config_;
  std::optional<bool> parked_;
  std::optional<Micros> calm_since_;  // locked, still, no alarm since
};

class ParkedController final : public MessageListener {
 public:
  ParkedController(ParkedConfig config, const domain::DomainTrackers& trackers, GatewayCore& core,
                   std::function<void(bool parked)> on_change = {});

  void on_message(const motinova::DecodedMessage&, Micros) override {}
  void tick(Micros now) override;
  std::optional<bool> parked() const { return mode_.parked(); }
  uint64_t changes() const { return changes_; }

 private:
  ParkedMode mode_;
  const domain::DomainTrackers& trackers_;
  GatewayCore& core_;
  std::function<void(bool)> on_change_;
  uint64_t changes_ = 0;
};

}  // namespace fleetgw::runtime
