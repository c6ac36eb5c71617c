// ZonesStage: the geofence (issue 14) as a stage of `fleetgw run` (runtime/stage.h). It owns the
// ZoneController (the bundle in force and its file, the zone engine, the MC enforcer) and all
// of the zones' policy: bundles judged, stored and enforced; locks made on the bike judged
// against the no-parking zones; lock and unlock commands judged for the command service; the
// outside_operating_area alarm raised and cleared; the enforcer's MC writes asked for one at a
// time. It never calls another stage: what it needs arrives as typed inputs, what it produced
// waits in typed outputs, and the Pipeline's routes move both (pipeline_zones.cc).
//
// Contract:
//  * Time: wall time from the Env it is given (positions, dwell, windows and alarms are judged
//    by when things were received, whatever the bus's possibly virtual timeline);
//    next_deadline() is the controller's next change (a ramp, a zone's time window) converted
//    to engine time through the same Env; "now" when inputs wait.
//  * Inputs (on the engine's thread): on_position() -- the current fix as the GNSS stage
//    reports it (nullopt: unknown or stale; it is also the fix bundles, bike locks and lock
//    commands are judged at); on_bundle() -- a retained zone-bundle message the uplink took;
//    on_lock_event() -- a lock event the lock tracker heard on the bus; set_mc() -- the MC as
//    the bus last showed it (assist level, speed limit in force) and whether the command
//    service is busy; on_write_started() / on_write_refused() / on_write_done() -- what became
//    of the MC write taken from `mc_write`.
//  * run(now) handles, in this order: the bundles received (each located at once at the
//    current fix), the positions (each change counts once towards a dwell), the bike locks
//    (report only: the lock has happened), then the controller's tick (windows opening or
//    closing, the next MC write). Every zone event is logged here and becomes a ZoneRecord.
//  * judge_lock() / judge_unlock() answer the command service's guards synchronously (a
//    stale or unknown position never refuses: a rider must always be able to end a ride);
//    the zone event they conclude waits in `records` like any other.
//  * Outputs, taken by the route: `records` (zone events with their row and serialised
//    payload: to store and queue, to the speed authority and the campaigns), `alarms` (the
//    outside_operating_area alarm raised or cleared), `mc_write` (at most one; the stage counts
//    it as running until on_write_refused() or on_write_done()), take_state_touched() (the
//    retained vehicle state may have changed).
//  * A refused bundle is logged once per distinct reason (a retained bundle comes again on
//    every reconnect); a refused MC write start is logged once per distinct reason and retried
//    by the enforcer.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "env/env.h"
#include "gateway/command/verifier.h"
#include "gateway/config/config.h"
#include "gateway/geofence/zone_controller.h"
#include "gateway/geofence/zone_lock_watch.h"
#include "gateway/gnss/position.h"
#include "gateway/runtime/stage.h"
#include "gateway/uplink/uplink.h"
#include "storage/records.h"

namespace fleetgw::runtime {

using motinova::Micros;

struct ZonesStageConfig {
  geofence::ZoneControllerConfig controller;
  // The bundle topics subscribed to: [0] the fleet's, [1] the vehicle's own (if any); empty
  // without [mqtt].
  std::vector<std::string> topics;
  std::size_t max_bundle_bytes = 0;  // [geofence] max_bundle_bytes (over it: refused unread)
};

// The stage's configuration from [geofence], [vehicle], [protocol] and [command] trusted_keys.
// The owner adds what other parts own: the speed authority (controller.enforcer.speed) and the
// delegated-document check of the command service.
ZonesStageConfig make_zones_stage_config(const config::Config& config);
// The zone-bundle topics of [geofence]: bundle_topic (default "<topic_prefix>/zones") and, with
// vehicle_bundles, "<topic_prefix>/<vehicle>/zones".
std::vector<std::string> zone_bundle_topics(const config::Config& config);

class ZonesStage final : public Stage {
 public:
  // `env` must outlive the stage.
  ZonesStage(ZonesStageConfig config, Env& env);

  std::string_view name() const override { return "zones"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;

  // Start-up: the stored bundle put in force (zones apply offline from the first fix).
  void restore();

  // Inputs (see the contract).
  void on_position(Micros wall, std::optional<gnss::Fix> position);
  void on_bundle(uplink::ZoneBundleMessage message);
  void on_lock_event(std::string_view kind, int new_raw, std::string_view cause);
  void set_mc(const geofence::McView& mc) { mc_ = mc; }
  void on_write_started();
  void on_write_refused(std::string why);
  void on_write_done(bool ok, std::string_view reason);

  // The command service's guards: a refusal's detail, or nullopt to let the command run.
  std::optional<std::string> judge_lock(bool ride_ending);
  std::optional<std::string> judge_unlock(bool ride_starting);

  // Outputs, taken by the route.
  struct ZoneRecord {
    geofence::ZoneEvent event;
    storage::ZoneEventRow row;
    storage::Bytes payload;  // fleetgw.v1.ZoneEvent
  };
  std::vector<ZoneRecord> records;
  struct AlarmRecord {
    storage::AlarmRow row;
    storage::Bytes payload;  // fleetgw.v1.Alarm
  };
  std::vector<AlarmRecord> alarms;
  struct McWriteRequest {
    command::McRequest request;
    std::string what;  // "speed limit 12 km/h", for the log
  };
  std::optional<McWriteRequest> mc_write;
  bool take_state_touched() { return std::exchange(state_touched_, false); }

  // For the status.
  const geofence::ZoneController& controller() const { return controller_; }
  bool outside_operating_area() const { return outside_operating_area_; }
  const std::vector<std::string>& topics() const { return topics_; }
  const std::string& bundle_file() const { return bundle_file_; }
  const std::string& last_refusal_topic() const { return bundle_refusal_topic_; }
  bool write_running() const { return write_running_; }

 private:
  struct BikeLock {
    Micros wall{0};
    std::optional<gnss::Fix> fix;  // current when the lock was heard
  };
  struct Position {
    Micros wall{0};
    std::optional<gnss::Fix> fix;
  };

  const gnss::Fix* fix() const { return fix_ ? &*fix_ : nullptr; }
  void emit(const geofence::ZoneEvent& e);  // log, and a ZoneRecord in `records`
  void handle_bundle(const uplink::ZoneBundleMessage& m, Micros wall);
  void update_area_alarm(Micros wall, const std::optional<gnss::Fix>& position);
  void tick(Micros wall);
  bool inputs_waiting() const {
    return !bundles_.empty() || !positions_.empty() || !bike_locks_pending_.empty();
  }

  Env& env_;
  geofence::ZoneController controller_;
  std::vector<std::string> topics_;
  std::string bundle_file_;
  std::size_t max_bundle_bytes_;
  std::optional<gnss::Fix> fix_;  // the current position as GNSS last reported it
  geofence::McView mc_;
  std::vector<uplink::ZoneBundleMessage> bundles_;
  std::vector<Position> positions_;
  geofence::BikeLockWatch bike_locks_;
  std::vector<BikeLock> bike_locks_pending_;
  bool write_running_ = false;           // an MC write of the zones is under way
  Micros write_at_{0};                   // when it was asked for
  std::string write_what_;               // what it writes, for the log
  std::string write_refusal_;            // the last reason a write could not start (logged once)
  bool outside_operating_area_ = false;  // the alarm is raised
  Micros area_alarm_since_{0};           // when it was raised
  std::string bundle_refusal_logged_;    // the last bundle refusal logged (each distinct once)
  std::string bundle_refusal_topic_;     // where the latest refused bundle came from
  bool state_touched_ = false;
};

}  // namespace fleetgw::runtime
