// Uplink: drains an OutboxSource to an MQTT broker as fleetgw.v1.Envelope messages (Paho MQTT
// C++ async client) and receives remote commands from the broker.
//
// Contract:
//  * Threading: Paho calls back on its own threads; those callbacks only queue events and call
//    the wake-up hook (connection change, publish completed, command arrived, diagnosis done).
//    All real work -- outbox reads and acks, publishing, reconnect decisions -- runs inside
//    poll(), on the owner's thread. poll() never calls out to the owner and is never re-entered:
//    commands are only queued, and the owner collects them with take_commands() after poll()
//    returns. The owner calls poll() when the wake-up hook fires, at next_deadline(), and after
//    adding records to the outbox. wait_for_events() serves owners without an event loop.
//    Apart from the wake-up hook and wait_for_events(), methods must not be called concurrently.
//  * Time: no clock is read for decisions; every entry point takes `now` (microseconds since the
//    Unix epoch) and back-off and telemetry batching run on that timeline.
//    next_deadline() converts the next due time to the steady clock of the Env the uplink is
//    given (env/env.h), anchored at the last poll; the connect diagnosis thread is started
//    through that Env too.
//  * Delivery: records leave in outbox order (priority, then sequence). A record is acked to the
//    outbox only when the publish carrying it completed successfully (PUBACK for QoS 1; written
//    to the socket for QoS 0 live telemetry). At most max_in_flight publishes are unacknowledged.
//    Failed or interrupted publishes leave their records in the outbox, so they are sent again:
//    duplicates are possible (consumers de-duplicate on vehicle id + sequence), loss is not.
//    Records whose payload does not decode as their kind's message, or of unknown kind, are
//    logged, counted (rejected_records) and removed, so one bad record cannot block the queue.
//    Telemetry samples are spliced into the batch as stored, never parsed (envelope_writer.h).
//    Every record's Envelope carries config.store_id: (vehicle_id, store_id, sequence) is its key.
//  * Session: client id = vehicle id, persistent session (clean_session = false). The retained
//    Status is a value the owner builds and hands over (set_status(); runtime/status_provider.h
//    builds the service's): the uplink never builds one and never calls out for one. It stamps
//    what only the connection knows (state ONLINE, connection CONNECTED, connected_at_us) and
//    publishes it at the next poll while connected; after a (re)connect, and when the refusals
//    in force changed, status_wanted() asks the owner for a fresh one (the one it holds was
//    built before). stop() publishes the latest one as OFFLINE/DISCONNECTED (a bare one if none
//    was ever handed). The last will is an offline Status marked last_will that carries only
//    what is known at connect (no outbox figures, created_at_us 0).
//  * MQTT 5 (config.protocol, the default; 3.1.1 is the fallback): a publish the broker refuses
//    with a PUBACK reason code >= 0x80 is not delivered: its records stay in the outbox, its
//    kind waits (the other kinds keep flowing; order within a kind is kept) and they are sent
//    again after that kind's back-off (reconnect_min .. reconnect_max, doubling while the
//    refusals go on); UplinkStats and every Status name every refused kind (code and name),
//    and the log says it once per distinct reason and topic. Every message carries the content
//    type and schema user property of mqtt5.h; the session asks for config.session_expiry and
//    the last will for config.will_delay. Under 3.1.1 a broker cannot refuse a publish: an ACL
//    that drops one still acknowledges it, and the record is gone (docs/uplink.md).
//  * Connect failures: each is diagnosed (connect_diagnosis.h) off the owner's thread; the reason
//    lands in UplinkStats::last_connect_error and is logged once per distinct reason, not per
//    retry.
//  * Security: TLS verification (chain and host name) on by default (mqtt_connection.h); the
//    password is never logged, URIs are logged without user information.
//  * Commands (docs/commands.md "Bursts and floods"): on Paho's thread, a payload on
//    <prefix>/<vehicle_id>/cmd larger than max_command_bytes is dropped before anything is copied
//    or parsed (and the heap is trimmed after large ones), one not decodable as
//    fleetgw.v1.SignedCommand is dropped too. The rest is judged by the owner's authenticator
//    (set_command_authenticator(): a pure signature check, one Ed25519 verification) BEFORE it
//    is queued, into separate lanes, so junk can never take an authenticated command's place:
//      - authenticated: at most max_queued_commands payloads wait for take_commands(); every
//        further one becomes a busy notice (id and digest only, at most kMaxBusyCommands = 1024
//        waiting) for take_busy_commands(), which the owner answers `busy`. Only beyond that
//        (more than max_queued_commands + 1024 authenticated commands arriving between two
//        polls) is one dropped unanswered, as "queue_full".
//      - unauthenticated (no trusted key's valid signature): at most
//        kMaxQueuedUnauthenticated = 4 wait on Paho's side, and poll() hands at most
//        kUnauthenticatedBurst = 10 at once and 30 per minute (a token bucket on the `now`
//        timeline) to take_commands(), where the owner answers them rate limited; the rest is
//        dropped as "unauthenticated". A junk flood thus costs the owner's thread at most 30
//        payloads a minute, and Paho's thread one verification per message (the bound on the
//        delay it adds to a genuine command queued behind it: docs/commands.md).
//    Without an authenticator (tests, tools) every decodable payload takes the authenticated
//    lane, without busy notices: beyond max_queued_commands it is dropped as "queue_full". Each
//    drop is counted by class (UplinkStats) and logged, at most once per 10 s per class with
//    the number suppressed since.
//  * Zone bundles (config.zone_topics, docs/location.md): each topic is subscribed (QoS 1) on
//    every connect, so the broker delivers its retained bundle each time. A payload larger than
//    max_zone_bundle_bytes is never copied: it is handed over as its size only (the owner refuses
//    it as too_large); others are handed over as received, unparsed (the owner's ZoneController
//    judges them). At most max_queued_zone_bundles wait for take_zone_bundles(); more are
//    dropped, logged and counted.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "env/env.h"
#include "fleetgw/v1/status.pb.h"
#include "gateway/uplink/outbox_source.h"
#include "gateway/uplink/topics.h"
#include "gateway/uplink/uplink_config.h"
#include "motinova/can.h"

namespace fleetgw::uplink {

using motinova::Micros;

// State of the uplink's MQTT connection (not the CAN bus link, can::ControllerState, nor the
// ConnectionState published in fleetgw.v1.Status).
enum class UplinkState {
  kStopped,             // not started, or stopped
  kConnecting,          // a connect attempt is under way
  kConnected,           // connected; draining the outbox
  kWaitingToReconnect,  // the last attempt failed or the connection dropped; see next_connect_at
};
std::string_view to_string(UplinkState state);

struct UplinkStats {
  UplinkState state = UplinkState::kStopped;
  std::uint64_t published_messages = 0;     // MQTT publishes handed to the client (incl. status)
  std::uint64_t published_records = 0;      // outbox records in those publishes (re-sends count)
  std::uint64_t acked_messages = 0;         // publishes whose token completed successfully
  std::uint64_t acked_records = 0;          // records acked (deleted) in the outbox
  std::uint64_t failed_publishes = 0;       // publishes that failed; their records stay
  std::uint64_t rejected_records = 0;       // undecodable / unknown-kind records dropped
  std::uint64_t bytes_published = 0;        // MQTT payload bytes handed to the client
  std::uint64_t connects = 0;               // successful connections
  std::uint64_t reconnects = 0;             // successful connections after the first
  std::uint64_t connect_failures = 0;       // failed connect attempts
  std::uint64_t connection_losses = 0;      // established connections that dropped
  std::uint64_t commands_received = 0;      // payloads handed to take_commands()
  std::uint64_t commands_dropped = 0;       // unanswered: the sum of the four classes below
  std::uint64_t zone_bundles_received = 0;  // handed to take_zone_bundles() (oversized included)
  std::uint64_t zone_bundles_dropped = 0;   // the queue was full
  std::size_t in_flight_messages = 0;       // publishes awaiting their token
  std::size_t in_flight_records = 0;        // records in those publishes
  std::size_t in_flight_high_water = 0;     // most publishes ever awaiting their token at once
  std::uint64_t outbox_depth = 0;           // from the OutboxSource
  std::int64_t oldest_unsent_created_us = 0;
  // Command payloads (the "Commands" lanes above): of commands_received, the unauthenticated
  // ones (answered rate limited); busy notices handed to take_busy_commands(); drops by class.
  std::uint64_t commands_unauthenticated = 0;
  std::uint64_t commands_busy = 0;
  std::uint64_t commands_dropped_oversized = 0;        // over max_command_bytes
  std::uint64_t commands_dropped_undecodable = 0;      // not a SignedCommand
  std::uint64_t commands_dropped_unauthenticated = 0;  // over the unauthenticated budget
  std::uint64_t commands_dropped_queue_full = 0;       // authenticated, over every bound
  std::int64_t last_publish_ok_us = 0;  // `now` of the poll that saw the last success; 0 never
  std::chrono::milliseconds last_backoff{0};  // the most recent reconnect delay chosen
  std::int64_t next_connect_at_us = 0;        // when kWaitingToReconnect: next attempt
  // Why the most recent connect attempt failed, e.g. "TLS: certificate verify failed (unable to
  // get local issuer certificate)", "TLS: host name mismatch", "connection refused",
  // "unreachable (...)", "not authorised"; empty once connected again.
  std::string last_connect_error;
  std::int64_t last_connect_error_us = 0;  // `now` when it was set; 0 when empty
  std::uint64_t tls_failures = 0;          // failed attempts whose reason is a TLS failure
  // MQTT 5: publishes the broker refused (PUBACK reason code >= 0x80) since start.
  std::uint64_t publish_refusals = 0;
  // The refusals in force, one per refused kind, "; "-separated, e.g. "0x87 Not authorized
  // (fleet/v1/bike-0042/alarm)"; a kind drops out once a publish of it is accepted (empty: none).
  std::string last_publish_refusal;
  int last_publish_refusal_code = 0;         // the latest one's reason code; 0 when empty
  std::int64_t last_publish_refusal_us = 0;  // `now` when the latest came; 0 when empty
  std::size_t refused_records = 0;           // records held for the next retry
  std::int64_t refusal_retry_at_us = 0;      // when they are retried; 0 = nothing held
};

// The owner's verdict on a command payload (set_command_authenticator()).
struct CommandTriage {
  bool authenticated = false;  // a trusted key's signature verifies over its command bytes
  std::string command_id;      // when authenticated
  std::string command_sha256;  // when authenticated: SHA-256 of the signed command bytes (raw)
};
// Runs on Paho's thread: must be thread-safe, must not block, and must judge only the payload
// (an immutable snapshot of the trusted keys; no journal, no clock).
using CommandAuthenticator = std::function<CommandTriage(std::string_view payload)>;

// An authenticated command the full queue could not take: the owner answers it `busy` (not
// journaled, so the same command sent again runs normally).
struct BusyCommand {
  std::string command_id;
  std::string command_sha256;
};

// A message of a zone-bundle topic, for the owner to judge.
struct ZoneBundleMessage {
  std::string topic;
  std::string payload;              // empty when oversized
  std::size_t oversized_bytes = 0;  // > 0: over max_zone_bundle_bytes, refused unread
};

class Uplink {
 public:
  // Validates the configuration (std::invalid_argument) and creates the MQTT client. Does not
  // connect. `outbox` and `env` must outlive the Uplink.
  Uplink(UplinkConfig config, OutboxSource& outbox, Env& env = Env::system());
  // Calls stop() with a short timeout if still running (an orderly offline status), then
  // releases the client.
  ~Uplink();
  Uplink(const Uplink&) = delete;
  Uplink& operator=(const Uplink&) = delete;

  // Set before start(). The wake-up hook is called on Paho threads: thread-safe, non-blocking.
  void set_wakeup(std::function<void()> wakeup);
  // Set before start(): sorts command payloads into the authenticated and unauthenticated lanes
  // on Paho's thread (see "Commands" above).
  void set_command_authenticator(CommandAuthenticator authenticator);
  // The retained status to publish (see "Session"): at the next poll while connected, stamped
  // with this connection's state, connection and connected_at_us (the rest is published as
  // given). Only the latest is kept; it is also what stop() publishes as OFFLINE.
  void set_status(fleetgw::v1::Status status);
  // The owner should build and hand a fresh status: connected, and none was handed since the
  // connection came up, or the publish refusals in force (UplinkStats) changed since.
  bool status_wanted() const;

  // Begins connecting.
  void start(Micros now);
  // Processes queued events, reconnects when due, publishes what the window allows.
  void poll(Micros now);
  // Blocks until a Paho event is queued or `max_wait` passed; true if events are queued.
  bool wait_for_events(std::chrono::milliseconds max_wait);
  // Commands received since the last call (raw serialized fleetgw.v1.SignedCommand payloads, in
  // arrival order; authenticated and, within their budget, unauthenticated ones), already
  // checked for size and decodability. Call after poll().
  std::vector<std::string> take_commands();
  // Authenticated commands the full queue could not take since the last call, in arrival order:
  // each must be answered `busy`. Call after poll(), after handling take_commands().
  std::vector<BusyCommand> take_busy_commands();
  // Zone-bundle messages received since the last call, in arrival order. Call after poll().
  std::vector<ZoneBundleMessage> take_zone_bundles();
  // Publishes one record that is not in the outbox (QoS 1, sequence 0), e.g. a command result
  // that could not be stored. `kind` is one of fleetgw::uplink::kind; `payload` its serialized
  // body message. False when not connected, when the payload does not decode as the kind's
  // message, or when the client refused it; true once handed to MQTT.
  bool publish_direct(std::string_view kind, std::string payload, Micros now);
  // The vehicle's last known state (a serialized fleetgw.v1.VehicleState body; `online` is set
  // here): published retained (QoS 1) on <prefix>/<vehicle>/state at the next poll while
  // connected, again after every (re)connect, and with online = false by stop(). Only the
  // latest one is kept: a state replaced before it could leave is never sent.
  void set_vehicle_state(std::string body);
  // Parked mode: telemetry batches wait up to `delay` instead of telemetry_batch_max_delay
  // (nullopt restores it; a batch already older than the restored delay leaves at the next
  // poll). Alarms and every other record are not batched and are not affected.
  void set_telemetry_batch_delay(std::optional<std::chrono::milliseconds> delay);
  // Latest time by which poll() should run again even without a wake-up, on the `now` timeline.
  Micros next_poll_due(Micros now) const;
  // The same as a steady_clock deadline (reconnect due, telemetry batch due, a handed status
  // to publish, stale resend); nullopt = poll only on a wake-up.
  std::optional<std::chrono::steady_clock::time_point> next_deadline() const;
  // A clean stop is coming: from now on a telemetry batch leaves at the next poll instead of
  // waiting for telemetry_batch_max_delay, so the owner can drain the outbox before stop().
  void drain_for_stop();
  // Publishes the retained offline status (when connected), disconnects and waits at most
  // `timeout` for each step. Records still in flight stay in the outbox.
  void stop(Micros now, std::chrono::milliseconds timeout = std::chrono::seconds(5));

  UplinkState state() const;
  UplinkStats stats() const;
  const Topics& topics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fleetgw::uplink
