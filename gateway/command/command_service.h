// CommandService: executes authenticated remote lock/unlock commands on the bike, exactly once,
// only when safe, and always with one definite, durable CommandResult.
//
// Contract:
//  * Clock-free and single-threaded: the runtime calls recover(now) once at start-up (before the
//    first payload), on_payload(bytes, now) for every message on <prefix>/<vehicle>/cmd (from
//    Uplink's command handler, on its loop thread), on_message(msg, now) with every decoded bus
//    message (motion interlock, MC and diagnostic answers), tick(now) with the node's tick, and
//    run(now) when next_due() says (runtime/command_stage.h: the command service as a stage of
//    the engine). Lock confirmations arrive through IotNode::actuate_lock callbacks inside the
//    node's on_frame()/tick().
//  * SQLite is written only from the entry points that handle a command or a document --
//    recover(), on_payload(), answer_busy(), answer_stopping(), on_revocations() -- and from
//    run(). The bus side (on_message(), tick() and the node's callbacks, which run inside the
//    CAN transport's read handler) never writes: a result concluded there (a lock confirmed or
//    timed out, an MC action or a diagnostic read answered) waits in memory (at most one per
//    running command: the locks, one MC action, one diagnostic read) until the next run() or
//    the next writing entry point, which writes it first; writes_pending() says so. The
//    journal's "executing" entry keeps a kill in between safe: recover() answers it.
//  * Outputs, taken by the runtime after each entry point: take_stored() (results queued in the
//    outbox since the last call: the uplink has something to publish) and take_unstored() (the
//    results the store refused, to publish directly; the runtime reports each hand-over with
//    unstored_handed()). The service never calls the uplink.
//  * Nothing touches the bus for a rejected command: verification (CommandVerifier), the
//    busy/shutdown checks, the lock-online check (NodeRegistry) and the interlocks all run
//    before the first CAN write.
//  * Exactly-once effect: an accepted command is journaled in SQLite (state "executing") BEFORE
//    the first CAN write; if the journal cannot be written the command is rejected
//    (storage_error) and nothing moves. A redelivered command (same id; QoS-1 duplicate) never
//    acts again: while it runs the duplicate is ignored (its result follows), afterwards the
//    stored result is queued again. recover(now) finishes journal entries a crash left
//    "executing" as `timeout` (reason "interrupted_by_restart") WITHOUT actuating again: a
//    status read could not tell whether our write or someone's key moved the lock, and a
//    definite "we do not know" is safer than a guess. The lock's real state still reaches the
//    backend as lock events.
//  * Exactly one CommandResult per authenticated command id (rejections included: the id is
//    journaled with the rejection). The one exception is `busy` (answer_busy(): the uplink's
//    queue was full): it says "not taken, nothing happened", is not journaled, and the same
//    command sent again gets its one real result. A result is written with the journal's final
//    state in ONE transaction, at outbox priority 0 (kind command_result, topic cmd/result) with
//    the serialized fleetgw.v1.CommandResult as payload, so it survives outages and restarts; each
//    stored result is counted for take_stored() (the pipeline publishes in the same settle).
//  * Every result carries command_sha256, the SHA-256 of the exact SignedCommand.command bytes
//    it answers, and `stored`. A payload that fails authentication never touches the journal,
//    the seen ids or the result table: its (rate limited) rejection goes to the outbox only,
//    bound to the forged bytes, so a genuine command with the same id executes normally and an
//    operator tool that checks the digest never mistakes the forgery's answer for its own.
//    Results for payloads that were not authentic (and re-sent results of duplicates) are rate
//    limited (`unauthenticated_results_per_minute`) so a flood of junk cannot fill the disk.
//  * A result the store refuses (disk full, I/O error) is still answered: it goes, serialized
//    with stored=false, to take_unstored(), which the pipeline publishes directly. Its journal
//    row and result row are kept in memory (bounded, `max_unjournaled`) and written by a later
//    run() (once a second) once the store accepts them -- with the outbox payload only if
//    unstored_handed() said it could not be handed to MQTT, and not before that report; until
//    then a redelivery of that id gets the same answer again, never a second execution.
//    A command whose "executing" entry cannot be journaled is rejected (storage_error) and
//    answered that way; nothing moves.
//  * Received strings quoted in reasons and logs are escaped and cut on code-point boundaries
//    (common/untrusted_text.h): a stored or published reason is always valid UTF-8 and one line.
//  * Interlocks per lock kind (InterlockRule): by default the frame, wheel and steering locks
//    never engage and the battery lock never releases while the bike moves: mc_status speed
//    above interlock_speed_kmh, or motor rpm > 0 within the last interlock_motor_window. Without
//    a recent mc_status (older than motion_max_age) motion is unknown and such actions are
//    refused too (motion_unknown_blocks), because a silent MC does not mean a still wheel.
//  * Execution: LockActuator via IotNode::actuate_lock (LOCK/UNLOCK per §3.5.4, confirmation by
//    status polling), confirm_timeout per attempt, `retries` more attempts after a timeout (never
//    after a reported failure: a jammed bolt is not forced). A whole-vehicle unlock sends the
//    vehicle UNLOCK broadcast (0x760/0x1206) first, then unlocks every fitted lock (wheel-type
//    locks first, so the bike can roll); a whole-vehicle lock locks every fitted lock in
//    `vehicle_lock_order` (seat, battery ... frame last) and then sends the vehicle LOCK
//    broadcast (0x760/0x1104). One lock at a time; a failing lock does not stop the sequence
//    (secure what can be secured), the overall result is the worst of the locks.
//  * Domain trackers (optional) are told before each actuation, so lock events carry the cause
//    "command:<id>".
//  * MC actions (Command.mc_action: speed limit, assist level, headlight, clear trip, power off)
//    take the same way in (authentication, freshness, replay, journal first, one result) and
//    are executed and confirmed from the bus by McActionRunner (mc_actions.h); the result
//    carries McActionResult. One MC action at a time; power off is refused while a lock
//    command runs, a lock moves or the bike moves (or its motion is unknown).
//  * Diagnostic reads (Command.diagnostic_read, issue 29) take the same way in too and are run
//    by DiagReader (diag_reader.h): read requests only, nothing is written to a node; one read
//    at a time (diag_busy), an MC read not while an MC action runs (mc_busy); a node that does
//    not answer in time gives TIMEOUT "node_offline: ..."; the result carries the decoded block
//    (CommandResult.diagnostic). The lifetime records seen on the bus are kept (DiagCapture)
//    and answer a read with last_captured without a bus request.
//  * Destroying the service mid-command is safe: pending node callbacks become no-ops, the
//    journal keeps "executing" and the next recover() finishes it.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/command/diag_reader.h"
#include "gateway/command/mc_actions.h"
#include "gateway/command/motion_interlock.h"
#include "gateway/command/verifier.h"
#include "gateway/node/iot_node.h"
#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::config {
struct Config;
}
namespace fleetgw::domain {
class DomainTrackers;
}
namespace fleetgw::geofence {
class SpeedAuthority;
}
namespace fleetgw::storage {
class Store;
}
namespace fleetgw::v1 {
class CommandResult;
class SignedDelegation;
}  // namespace fleetgw::v1

namespace fleetgw::command {

struct CommandServiceConfig {
  VerifierConfig verifier;
  // Lock-state names (U19) and the mc_status reading used by the interlock.
  motinova::DecodeOptions decode_options{};
  std::map<std::string, InterlockRule> interlocks = default_interlocks();
  double interlock_speed_kmh = 1.0;
  Micros interlock_motor_window = 5s;
  Micros motion_max_age = 1s;
  bool motion_unknown_blocks = true;
  Micros confirm_timeout = 3s;  // per attempt
  int retries = 1;              // extra attempts after a timeout
  // Whole-vehicle lock order by kind; kinds not listed go first (LOCK index order). Unlock
  // runs in the reverse order.
  std::vector<std::string> vehicle_lock_order{"seat",  "battery", "other",     "steering",
                                              "frame", "wheel",   "rear_wheel"};
  // Rejected ids are remembered at least this long (even when already expired), so a
  // redelivery gets the same answer instead of a second result.
  Micros rejected_retention = 10min;
  int unauthenticated_results_per_minute = 30;
  Micros purge_interval = 60s;
  // Results the store refused, kept for a later journal write; beyond this the oldest is
  // given up (counted in CommandStats::unjournaled_dropped).
  std::size_t max_unjournaled = 256;
  // MC actions (issue 13). Its decode_options, confirm_timeout and retries are taken from the
  // fields above when the service is built.
  McActionConfig mc{};
  // Diagnostic reads (issue 29). Its decode_options are taken from the field above.
  DiagReaderConfig diag{};
};

// Fills the config from fleetgw.toml: [vehicle].id, [command], [protocol] lock kinds and names.
CommandServiceConfig make_command_service_config(const config::Config& config);

// "Is the wall clock synchronised?" default: now is after 2024-01-01T00:00:00Z (a board that
// booted without RTC or NTP sits in 1970 or at its build date).
bool default_clock_synchronised(Micros now);

// What the service needs from the runtime. Everything referenced must outlive the service.
struct CommandContext {
  node::IotNode& node;
  storage::Store& store;
  domain::DomainTrackers* trackers = nullptr;
  std::function<bool(Micros)> clock_synchronised = default_clock_synchronised;
  // The wall clock commands are judged by. Commands carry wall-clock issued/expiry times, so
  // freshness, replay retention and purging must follow the wall clock even when the bus
  // timeline is simulated faster than real time or replayed from a log; timeouts and the
  // interlocks follow the `now` of the calls (the bus timeline). Empty: `now` is the wall clock.
  std::function<Micros()> wall_clock;
};

enum class Disposition : std::uint8_t {
  kRejected,             // a rejected result was produced (nothing touched the bus)
  kStarted,              // accepted, journaled, actuation under way
  kDuplicateInProgress,  // same id still executing: ignored, the result follows
  kDuplicateAnswered,    // same id finished earlier: its stored result was queued again
  kDropped,              // not answered: result rate limit reached (counted and logged)
  kBusy,                 // answered `busy` (answer_busy()): not judged, not journaled
};
std::string_view disposition_name(Disposition d);

struct CommandStats {
  std::uint64_t payloads = 0;
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;
  std::uint64_t succeeded = 0;
  std::uint64_t failed = 0;
  std::uint64_t timed_out = 0;
  std::uint64_t duplicates = 0;
  std::uint64_t recovered = 0;
  std::uint64_t results_dropped = 0;  // rate limit
  std::uint64_t storage_errors = 0;
  std::uint64_t results_unstored = 0;               // put in take_unstored()'s output
  std::uint64_t unstored_not_published = 0;         // unstored_handed(..., false)
  std::uint64_t unjournaled_dropped = 0;            // given up: max_unjournaled exceeded
  std::map<std::string, std::uint64_t> rejections;  // by reason name
};

// The signature check the uplink runs on Paho's thread before a payload is queued
// (docs/commands.md "Bursts and floods"): authenticated means a trusted key's valid signature
// over the command bytes (checks 1-3 of verifier.h passed; a command for another vehicle is
// authenticated too, and refused later as wrong_vehicle).
struct PayloadAuthentication {
  bool authenticated = false;
  std::string command_id;      // when authenticated
  std::string command_sha256;  // when authenticated: SHA-256 of the signed command bytes
};
using PayloadAuthenticator = std::function<PayloadAuthentication(std::span<const std::uint8_t>)>;

// A result the store refused (CommandService::take_unstored()), to be published directly on the
// command-result topic.
struct UnstoredResult {
  std::string command_id;  // empty for a result not about a journaled command
  std::string serialized;  // fleetgw.v1.CommandResult, stored = false
};

class CommandService {
 public:
  // Called with every result produced or re-sent, after it was stored (stored() true) or put
  // in take_unstored()'s output (stored() false). For tests, live view.
  using ResultObserver = std::function<void(const v1::CommandResult& result, bool resent)>;

  // Throws std::invalid_argument for a bad configuration (trusted keys, vehicle id).
  CommandService(CommandServiceConfig config, CommandContext context);
  ~CommandService();
  CommandService(const CommandService&) = delete;
  CommandService& operator=(const CommandService&) = delete;

  // Finishes journal entries left "executing" by a previous run; returns how many.
  std::size_t recover(Micros now);
  Disposition on_payload(std::span<const std::uint8_t> payload, Micros now);
  Disposition on_payload(std::string_view payload, Micros now);
  // An authenticated command the uplink's full queue could not take (Uplink::
  // take_busy_commands()). A new id is answered `rejected`, reason "busy: ...", always (no rate
  // limit), bound to `command_sha256`, and NOT journaled or marked as seen: the same command
  // sent again is judged and run normally. An id this service already answered or is running is
  // treated as the redelivery it is (the stored result again, or nothing while it runs), and a
  // different command reusing such an id as `replayed`: never two different answers for one id.
  Disposition answer_busy(std::string_view command_id, std::string_view command_sha256, Micros now);
  // A command that reached the gateway while it stops (still in the uplink's queue, or arriving
  // during the drain): authenticated like any payload (junk gets its rate-limited answer), then
  // answered `rejected`, reason "shutting_down: ...", exactly like answer_busy() (not journaled,
  // not marked as seen, a known id answered as the redelivery it is): never run, never lost
  // without a result; the sender may send it again once the bike is back.
  Disposition answer_stopping(std::span<const std::uint8_t> payload, Micros now);
  // A stateless, thread-safe signature check over an immutable copy of the trusted keys (it
  // shares nothing with this service and may outlive it): for the uplink's Paho thread. One
  // SignedCommand and one Command parse and at most one Ed25519 verification per call.
  PayloadAuthenticator authenticator() const;
  // The bus side (see the contract): in memory only, never SQLite.
  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);

  // The due work: the results concluded on the bus written (each with its journal's final
  // state, in one transaction), the journal rows the store refused retried (once a second),
  // expired ids purged (once a minute), the captured lifetime records persisted.
  void run(Micros now);
  // The earliest bus time at which run() has work (`now` itself while writes_pending()); nullopt
  // when only new input can give it work.
  std::optional<Micros> next_due(Micros now) const;
  // Results concluded on the bus wait for their write.
  bool writes_pending() const;
  // Outputs. Results queued in the outbox since the last call.
  std::size_t take_stored();
  // Results the store refused, to publish directly, oldest first.
  std::vector<UnstoredResult> take_unstored();
  // Whether the unstored result of `command_id` reached MQTT: if not, it is queued in the outbox
  // with its journal row once the store accepts writes.
  void unstored_handed(std::string_view command_id, bool handed);

  void set_result_observer(ResultObserver observer);
  // Issue 14: asked before a lock command that locks touches the bus (after the interlocks),
  // with ride_ending true for a whole-vehicle lock or a frame or wheel lock. A returned detail
  // refuses the command (rejected, no_parking_zone: <detail>); nullopt lets it run.
  using LockGuard = std::function<std::optional<std::string>(bool ride_ending, Micros now)>;
  void set_lock_guard(LockGuard guard);
  // Issue 27: the same before an unlock command that unlocks, with ride_ending read as "ride
  // starting" (a whole-vehicle unlock or a frame or wheel lock); a detail refuses it (rejected,
  // no_start_zone: <detail>).
  void set_unlock_guard(LockGuard guard);
  bool busy() const;
  // An MC action on the gateway's own behalf (issue 14: a geofence's speed limit or assist
  // cap): the same pre-flight and bus confirmation as a remote MC command, but no journal and
  // no CommandResult. Returns the refusal when it cannot start now (another MC action or a lock
  // command running, the MC offline...); otherwise `done` runs once with the outcome. A remote
  // MC command arriving meanwhile is refused as mc_busy, as during any MC action.
  using OwnMcDone = std::function<void(bool succeeded, std::string reason, Micros now)>;
  std::optional<Rejection> start_own_mc_action(const McRequest& request, Micros now,
                                               OwnMcDone done);
  // Issue 24: the bike's one speed-limit authority (gateway/geofence/speed_authority.h), the
  // operator's cap restored from the store; the zone enforcer shares it. Lives as long as the
  // service.
  geofence::SpeedAuthority& speed_authority();
  // Issue 28: a payload of <prefix>/<vehicle>/revocations (a serialized SignedRevocationList).
  // Judged by the verifier (delegation.h Revocations::offer); an accepted list is in force at
  // once and stored in the store's meta table ("command.revocations"), so it is enforced after
  // a restart without the broker. A store failure is logged; the list is enforced all the same.
  RevocationVerdict on_revocations(std::span<const std::uint8_t> payload, Micros now);
  // The highest revocation list version in force (0: none), for `fleetgw status`.
  std::uint64_t revocation_version() const;
  // Issue 28: the check of a zone bundle (or another document) signed under a delegation, with
  // this service's root keys, vehicle identity, revocation lists and wall clock; `action` is the
  // delegation action the document needs ("zones"). Valid while the service lives.
  using DelegatedDocumentCheck = std::function<DelegatedCheck(
      const v1::SignedDelegation& delegation, std::string_view signer_key_id,
      std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature)>;
  DelegatedDocumentCheck delegated_document_check(std::string action) const;
  // Results the store refused that still wait for their journal write.
  std::size_t unjournaled() const;
  const CommandStats& stats() const;
  const CommandServiceConfig& config() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;  // shared so pending node callbacks can detect our destruction
};

}  // namespace fleetgw::command
