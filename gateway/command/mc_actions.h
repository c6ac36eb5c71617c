// McActionRunner: executes the remote actions on the motor controller and the system (issue
// 13) -- speed limit, assist level, headlight, clear trip, power off -- and confirms each from
// the bus, never from the fact that a frame was sent. Journal, results and authentication stay
// with the CommandService; this part only talks to the bike.
//
// Contract:
//  * Clock-free and single-threaded like the CommandService: start(), on_message() and tick()
//    take `now` (bus timeline); node callbacks (request answers, shutdown outcome) arrive inside
//    IotNode::on_frame()/tick(). One action at a time (busy()).
//  * preflight() runs before the command is journaled and before anything is sent: MC offline,
//    another MC action running, the MC's current state unknown (assist/headlight/clear trip need
//    a running-data frame 0x710/0x1020 no older than `state_max_age`), an unknown assist-level
//    name, a speed limit outside the MC's range when the MC's settings report (0x5408) is
//    already known, and for power off the motion interlock (moving / motion unknown) and any
//    lock in motion. A refused action puts nothing on the bus.
//  * Speed limit (spec 3.5.2, 3.4.3, 3.2.8): read the settings (0x761 0x3300 -> 0x5408), refuse
//    a limit outside [max(1, factory - 50), factory] (`out_of_range`, code REJECTED, nothing
//    written; 0 is refused at once), write 0x3408 with the wheel adjustment and mode copied from
//    the report and the new offset (limit - factory), then read the settings again: the offset
//    read back must be the one written. What is written is the limit in force (issue 24): for a
//    remote command (McRequest::sets_operator_cap) the SpeedAuthority's minimum with the
//    requested cap -- inside a 12 km/h zone a request of 25 writes 12, never 25 -- and when the
//    MC already reports it, nothing is written (`succeeded`, writes_sent 0). The runner holds
//    the bike's one SpeedAuthority (speed()); recording the cap is the command service's. Whether
//    0x5408 byte 2 is the factory limit (best guess) or the limit in force is uncertain [G]:
//    `settings_limit_is_factory`.
//  * Assist level and headlight (0x761 0x3002, one frame for both): the other half is copied
//    from the latest running data; confirmed when a running-data frame after the write shows
//    both values. Clear trip (0x761 0x3605 CLEAR): confirmed when a running-data frame after
//    the write shows a trip of at most `trip_cleared_max_dm` and a trip time no longer than the
//    time since the write (+1 s).
//  * No confirmation within `confirm_timeout` after a write: the write is repeated up to
//    `retries` times; then `failed` ("not_confirmed: ...") when the MC answered but showed
//    something else, `timeout` ("no_answer: ...") when it did not answer at all. A settings
//    read is retried and timed out by the RequestEngine (200 ms / 1 s, spec 3.7).
//  * Power off (spec 3.8.2): IotNode::start_shutdown_observed (the ACC hook still runs);
//    `succeeded` when every awaited READY (MC, and the OBC if online) arrived, `timeout` when
//    none did, `failed` when only some did. The power goes off in every case (the spec's 1 s).
//  * The Done callback runs exactly once per start(), after the runner is idle again (it may
//    start the next action). Destroying the runner mid-action is safe: pending node callbacks
//    become no-ops and Done is never called.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/motion_interlock.h"
#include "gateway/command/verifier.h"
#include "gateway/geofence/speed_authority.h"
#include "gateway/node/iot_node.h"
#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::command {

struct McActionConfig {
  motinova::DecodeOptions decode_options{};  // assist names (U7), data order, MC answer ID
  Micros confirm_timeout = 3s;               // per write attempt
  int retries = 1;                           // more write attempts after an unconfirmed one
  // [G] 0x5408 byte 2: the factory limit (true, best guess; the limit in force is byte 2 +
  // byte 6) or the limit in force (false; the factory limit is byte 2 - byte 6).
  bool settings_limit_is_factory = true;
  int max_offset_kmh = 50;  // 0x3408 offset range -50..0 (spec 3.4.3)
  Micros state_max_age = 2s;
  int trip_cleared_max_dm = 1;      // 0.1 km: a bike rolling during the confirmation adds a little
  Micros lock_motion_max_age = 2s;  // a lock status "unlocking/locking" younger than this moves
};

struct McOutcome {
  v1::CommandResultCode code = v1::COMMAND_RESULT_CODE_UNSPECIFIED;
  std::string reason;  // "<code>: <detail>", empty on success
  v1::McActionResult details;
};

class McActionRunner {
 public:
  using Done = std::function<void(McOutcome outcome, Micros now)>;

  McActionRunner(McActionConfig config, node::IotNode& node, MotionInterlock& motion);
  ~McActionRunner();
  McActionRunner(const McActionRunner&) = delete;
  McActionRunner& operator=(const McActionRunner&) = delete;

  // The refusal (reason, detail; no command id) of `request` right now, if any.
  // `lock_command_running`: the CommandService has a lock command in progress.
  std::optional<Rejection> preflight(const McRequest& request, bool lock_command_running,
                                     Micros now);
  // Starts an action that passed preflight() (re-checked; a refusal then completes as FAILED).
  void start(const McRequest& request, Micros now, Done done);
  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  bool busy() const { return job_ != nullptr; }
  const McActionConfig& config() const { return config_; }
  // The bike's speed-limit authority (speed_authority.h): every speed-limit write is decided
  // by it; the zone enforcer shares it through CommandService::speed_authority().
  geofence::SpeedAuthority& speed() { return speed_; }
  const geofence::SpeedAuthority& speed() const { return speed_; }
  // Set once the operator's cap was restored from the store (CommandService, at first use).
  bool cap_restored = false;

 private:
  struct Job;
  struct Settings;
  struct Running;

  std::optional<Running> latest_running(Micros now) const;
  std::optional<Settings> latest_settings() const;
  std::optional<Settings> settings_from(const motinova::AppFrame& frame) const;
  std::optional<std::uint8_t> assist_value(std::string_view name) const;
  std::string assist_name(std::int64_t raw) const;
  bool lock_moving(Micros now) const;

  void read_settings(Micros now);
  void on_settings(const node::RequestResult& res);
  void write(Micros now);
  bool confirmed(const Running& r, Micros now) const;
  void record(const Running& r);
  void attempt_over(Micros now);
  void finish(v1::CommandResultCode code, std::string reason, Micros now);

  McActionConfig config_;
  node::IotNode& node_;
  MotionInterlock& motion_;
  geofence::SpeedAuthority speed_{std::nullopt};  // own limit: set by the runtime's [geofence]
  std::shared_ptr<Job> job_;                      // shared so node callbacks can tell it is gone
};

}  // namespace fleetgw::command
