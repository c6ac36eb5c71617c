// StateStage: the retained last-known vehicle state (runtime/vehicle_state.h, topic
// <prefix>/<vehicle>/state) and parked mode (runtime/parked_mode.h) as a stage of `fleetgw run`
// (runtime/stage.h). It owns the state's throttle and position filter and the parked
// controller; it never calls another stage: its inputs arrive from the Pipeline's routes, and
// the state to publish and the parked/riding rates wait in typed outputs the routes apply
// (pipeline_state.cc).
//
// Contract:
//  * next_deadline() is the throttle's (the last hand-over + state_interval_ms once something
//    was touched, at once for the first; none when nothing was touched or the state is
//    disabled). run(now) checks when it is due: the state is rebuilt from the sources and put in
//    `state` only when it differs from the last one handed over (GNSS jitter within
//    state_min_move_m is no change).
//  * Inputs: touch() -- the state's inputs may have changed (frames, an alarm, a bundle, the
//    core's timer turn); on_position() -- the current fix as the GNSS stage reports it (also a
//    touch); set_outside_operating_area() -- the zones' alarm (listed after the tracker's own).
//  * Sources are read, never called: the live state, the alarm tracker, the bus health and the
//    BusClock (updated_at_us is bus time), at the moment of the check -- a copy at every frame
//    would cost more than the check.
//  * Parked mode: parked_listener() is added to the GatewayCore after the Recorder; it judges at
//    every listener tick and sets the poller's parked period itself (in that tick, on the bus
//    timeline, so no request goes out at the old rate). A change touches the state and puts the
//    uplink's rates in `rates` (the telemetry batch delay while parked, none while riding);
//    `signal` is then called so that the owner settles and applies them.
//  * check_now(): a check whatever the throttle says (the state a clean stop leaves retained);
//    false when the state is disabled or unchanged.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>

#include "env/env.h"
#include "gateway/can/transport.h"
#include "gateway/config/config.h"
#include "gateway/domain/domain_trackers.h"
#include "gateway/gnss/position.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/parked_mode.h"
#include "gateway/runtime/stage.h"
#include "gateway/runtime/vehicle_state.h"

namespace fleetgw::runtime {

struct StateStageConfig {
  // [mqtt] state_interval_ms; 0 (or [mqtt] disabled): no retained state.
  std::chrono::milliseconds min_interval{0};
  double min_move_m = 0;  // [mqtt] state_min_move_m
  ParkedConfig parked;
  std::chrono::milliseconds parked_batch_delay{0};  // [parked] telemetry_batch_ms
};

ParkedConfig make_parked_config(const config::Config& config);
StateStageConfig make_state_stage_config(const config::Config& config);

// What the state is built from (see the contract); each must outlive the stage.
struct StateSources {
  GatewayCore& core;  // the live state; the node's poller (parked polling)
  const domain::DomainTrackers& trackers;
  const BusClock& clock;
  const can::Transport& transport;
};

class StateStage final : public Stage {
 public:
  StateStage(StateStageConfig config, StateSources sources, Env& env,
             std::function<void()> signal = {});

  std::string_view name() const override { return "vehicle_state"; }
  std::optional<EngineTime> next_deadline() const override { return throttle_.deadline(); }
  StageRun run(EngineTime now) override;

  // Inputs.
  void touch() { throttle_.touch(); }
  void on_position(std::optional<gnss::Fix> position);
  void set_outside_operating_area(bool outside);

  bool enabled() const { return throttle_.enabled(); }
  bool check_now();
  // Parked (locked and still) or riding; nullopt before the first evaluation.
  std::optional<bool> parked() const { return parked_.parked(); }
  MessageListener& parked_listener() { return parked_; }

  // Outputs, taken by the route: the serialized fleetgw.v1.VehicleState to hand to the uplink
  // (online left false: the uplink sets it) ...
  std::optional<std::string> state;
  // ... and the uplink's rates after a parked/riding change.
  struct Rates {
    bool parked = false;
    std::optional<std::chrono::milliseconds> telemetry_batch_delay;  // nullopt: riding
  };
  std::optional<Rates> rates;

 private:
  bool check(EngineTime now);
  void on_parked(bool parked);

  StateSources sources_;
  Env& env_;
  std::function<void()> signal_;
  std::chrono::milliseconds parked_batch_delay_;
  StateThrottle throttle_;
  StatePositionFilter position_filter_;
  std::optional<gnss::Fix> position_;
  bool outside_operating_area_ = false;
  ParkedController parked_;
};

}  // namespace fleetgw::runtime
