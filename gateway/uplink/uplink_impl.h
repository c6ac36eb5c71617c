// Internal to the uplink: the state behind Uplink (uplink.h), shared by uplink.cc (lifecycle:
// connect, diagnose, reconnect, stop, event dispatch) and uplink_publish.cc (outbox draining,
// telemetry batching, publishing and acks).
//
// Contract: every member is touched only on the owner's thread (inside Uplink's methods),
// except `events` and the listeners, which Paho's threads and the diagnosis thread use, and
// which are declared so that they are destroyed after the client and the diagnosis thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include <mqtt/async_client.h>

#include "fleetgw/v1/status.pb.h"
#include "gateway/uplink/backoff.h"
#include "gateway/uplink/command_inbox.h"
#include "gateway/uplink/envelope_writer.h"
#include "gateway/uplink/uplink.h"
#include "gateway/uplink/uplink_events.h"

namespace fleetgw::uplink {

struct Uplink::Impl {
  struct PendingBatch {
    TelemetryBatchWriter writer;
    std::vector<std::uint64_t> seqs;
    std::size_t bytes = 0;
    std::int64_t oldest_created_us = 0;
    std::int64_t newest_created_us = 0;
    std::int64_t first_created_us = 0;
    bool empty() const { return seqs.empty(); }
  };
  struct InFlightEntry {
    std::vector<std::uint64_t> seqs;  // outbox records carried; empty for other messages
    int qos = 1;
    std::uint64_t connection = 0;        // counters.connects when it was sent
    const std::string* topic = nullptr;  // a member of `topics` (for refusal messages)
  };

  Impl(UplinkConfig c, OutboxSource& o, Env& e);
  std::unique_ptr<mqtt::async_client> make_client();
  void recycle_client(Micros now);

  // ---- Paho thread ----
  void on_message(const mqtt::message& msg);
  void on_zone_message(const mqtt::message& msg);

  // ---- owner's thread: lifecycle (uplink.cc) ----
  mqtt::connect_options make_connect_options(Micros now) const;
  void connect(Micros now);
  void on_connect_failed(Micros now, int rc, const std::string& message, int reason = 0);
  void on_diagnosed(Micros now, const detail::ConnectDiagnosed& d);
  void set_connect_error(Micros now, const std::string& reason);
  void schedule_reconnect(Micros now);
  void on_connected(Micros now);
  void on_connection_lost(Micros now, const std::string& cause);
  void poll(Micros now);
  void handle(Micros now, detail::ConnectDone& e);
  void handle(Micros now, detail::ConnectionLost& e);
  void handle(Micros now, detail::PublishDone& e);
  void handle(Micros now, detail::SubscribeDone& e);
  void handle(Micros now, detail::CommandArrived& e);
  void handle(Micros now, detail::CommandBusy& e);
  void discard_command_events(const std::deque<detail::Event>& leftover);  // uplink_commands.cc
  void handle(Micros now, detail::CommandDropped& e);
  void handle(Micros now, detail::ZoneBundleArrived& e);
  void handle(Micros now, detail::ZoneBundleDropped& e);
  void handle(Micros now, detail::ConnectDiagnosed& e);
  void stop(Micros now, std::chrono::milliseconds timeout);
  Micros next_due(Micros now) const;

  // ---- owner's thread: publishing (uplink_publish.cc) ----
  EnvelopeHeader header(std::uint64_t seq, std::int64_t created_us) const;
  std::string serialize_status(Micros now, v1::OnlineState online, v1::ConnectionState conn) const;
  std::string serialize_will(Micros connecting_at) const;
  void publish_status(Micros now);
  bool publish(const std::string& topic, std::string payload, int qos, bool retained,
               std::vector<std::uint64_t> seqs);
  bool publish_direct(std::string_view kind, std::string payload, Micros now);
  mqtt::message_ptr make_message(const std::string& topic, std::string payload, int qos,
                                 bool retained) const;
  void on_publish_done(Micros now, const detail::PublishDone& d);
  void on_refused(Micros now, const std::string& topic, std::vector<std::uint64_t> seqs,
                  int reason);
  void on_accepted(std::string_view kind);
  void refusals_changed(std::string_view kind);
  void retry_refused(Micros now);
  void forget_refused();
  KindSet blocked_kinds() const;
  void resend_stale(Micros now);
  void release(const std::vector<std::uint64_t>& seqs);
  void reject(const OutgoingRecord& e, std::string_view why);
  std::size_t capacity() const;
  void flush_batch(Micros now);
  bool batch_due(Micros now) const;
  bool add_telemetry(Micros now, const OutgoingRecord& e);
  bool publish_record(const OutgoingRecord& e);
  void drain(Micros now);

  // ---- owner's thread: the retained vehicle state (state_publish.cc) ----
  void publish_vehicle_state(Micros now, bool online);

  UplinkConfig config;
  OutboxSource& outbox;
  Env& env;
  Topics topics;
  Backoff backoff;
  // ---- MQTT 5 (docs/uplink.md, "MQTT 5") ----
  mqtt::properties envelope_props;  // on every publish under MQTT 5; empty under 3.1.1
  // Publishes the broker refused (PUBACK reason code >= 0x80), one lane per kind (the topic's
  // kTopicTable entry): a refused kind's records stay claimed until the lane's retry time, its
  // newer records are not drawn from the outbox meanwhile (order within a kind is kept), and
  // every other kind keeps flowing. A lane's wait doubles while its refusals go on, so a
  // refusing broker costs one window of that kind per back-off period, never a hot loop; any
  // accepted publish of the kind closes the lane.
  struct RefusedLane {
    explicit RefusedLane(Backoff b) : backoff(b) {}
    std::vector<std::uint64_t> held;  // claimed, waiting for retry_at
    Backoff backoff;
    Micros retry_at{0};  // 0 = nothing held: the kind is drawn again
    std::string why;     // "0x87 Not authorized (<topic>)"
    int code = 0;
    Micros at{0};  // `now` of its latest refusal
  };
  struct RefusedLanes {
    std::map<std::string, RefusedLane, std::less<>> by_kind;
    // Records held for a retry, all kinds (UplinkStats::refused_records).
    std::size_t size() const;
  };
  Backoff refusal_backoff;     // copied into each new lane (and stepped, so their jitter differs)
  RefusedLanes refused_held;   // by kind
  Micros refusal_retry_at{0};  // the earliest lane's retry; 0 = no records held
  std::set<std::string> logged_refusals;  // each distinct reason (and topic) logged once
  UplinkState state = UplinkState::kStopped;
  UplinkStats counters;
  v1::Status status;            // the latest the owner handed (set_status); empty = none yet
  bool status_due = false;      // handed and not yet published on this connection
  bool status_wanted = false;   // connected and the owner should hand a fresh one
  bool first_poll_due = false;  // connected in the last poll: the next one publishes
  std::string vehicle_state;       // latest VehicleState body from the owner; empty = none
  bool vehicle_state_due = false;  // not yet published on this connection
  std::chrono::milliseconds batch_delay{0};  // telemetry_batch_max_delay, or the parked one
  bool draining = false;  // drain_for_stop(): telemetry batches leave without waiting
  detail::CommandInbox commands;                // lanes and hand-over (uplink_commands.cc)
  std::vector<ZoneBundleMessage> zone_bundles;  // waiting for take_zone_bundles()
  std::uint64_t connect_attempt = 0;
  std::uint64_t publish_id = 0;
  std::unordered_map<std::uint64_t, InFlightEntry> in_flight;
  std::set<std::uint64_t> claimed;  // in flight or in the pending batch
  PendingBatch batch;
  bool head_is_telemetry = true;  // the last outbox read ended in telemetry records
  Micros connected_at{0};
  Micros connect_started{0};  // `now` of the attempt that made (or makes) the connection
  Micros last_now{0};  // the latest `now` we were given (for the destructor's offline status)
  std::string logged_connect_error;  // the reason last logged (each distinct one logged once)
  bool last_failure_was_tls = false;
  bool diagnosis_done = true;  // the diagnosis thread's result was handled
  Micros heap_trim_due{0};     // 0 = none; after a large command was dropped
  Micros recycle_due{0};       // 0 = none; when to replace the client after a large command
  Micros last_recycle{0};
  std::chrono::steady_clock::time_point last_poll_steady{};  // when `last_now` was given

  // Declared last, destroyed first (reverse order): the diagnosis thread and Paho may still
  // push events while they shut down, so the queue and listeners must outlive them.
  detail::EventQueue events;
  detail::ConnectListener connect_listener;
  detail::PublishListener publish_listener;
  detail::SubscribeListener subscribe_listener;
  // A pointer so it can be replaced: Paho C keeps a read buffer as large as the largest packet
  // it ever received until its last client is destroyed (recycle_client()).
  std::unique_ptr<mqtt::async_client> client;
  std::jthread diagnosis;  // at most one diagnosis at a time
};

}  // namespace fleetgw::uplink
