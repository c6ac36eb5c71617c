// Uplink lifecycle: construction, connect and reconnect with back-off, diagnosis of failed
// connects, connection loss, the event dispatch of poll(), stop, and the public API. Publishing
// and the outbox drain live in uplink_publish.cc.
#include "gateway/uplink/uplink.h"

#include <malloc.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>
#include <random>
#include <utility>

#include "gateway/uplink/connect_diagnosis.h"
#include "gateway/uplink/mqtt5.h"
#include "gateway/uplink/mqtt_connection.h"
#include "gateway/uplink/tcp_nodelay.h"
#include "gateway/uplink/uplink_impl.h"

namespace fleetgw::uplink {

std::string_view to_string(UplinkState state) {
  switch (state) {
    case UplinkState::kStopped:
      return "stopped";
    case UplinkState::kConnecting:
      return "connecting";
    case UplinkState::kConnected:
      return "connected";
    case UplinkState::kWaitingToReconnect:
      return "waiting_to_reconnect";
  }
  return "unknown";
}

namespace {

using std::chrono::duration_cast;
using std::chrono::milliseconds;

using detail::kTrimAfterBytes;  // command_inbox.h
// The trim waits until Paho has freed its own copies of the message.
constexpr Micros kTrimDelay = std::chrono::milliseconds(200);
// The client is replaced at most this often after oversized messages (recycle_client()).
constexpr Micros kRecycleInterval = std::chrono::seconds(60);
// Each step of a connect diagnosis waits at most this long (also bounds the destructor's wait).
constexpr milliseconds kProbeTimeout{2000};

// The text of an MQTT 5 CONNACK refusal: the 3.1.1 wording where one exists (the same reason
// reads the same under both protocols), the code and Paho's name otherwise.
std::string connack_v5_reason(int reason) {
  switch (reason) {
    case 0x84:
      return "refused by the broker: unsupported protocol version (set [mqtt] protocol = "
             "\"3.1.1\" for a broker without MQTT 5)";
    case 0x85:
      return "refused by the broker: client identifier rejected";
    case 0x86:
      return "not authorised: bad user name or password";
    case 0x87:
      return "not authorised";
    case 0x88:
      return "refused by the broker: server unavailable";
    default:
      return "refused by the broker: " + reason_text(reason);
  }
}

}  // namespace

Uplink::Impl::Impl(UplinkConfig c, OutboxSource& o, Env& e)
    : config((c.validate(), std::move(c))),
      outbox(o),
      env(e),
      topics(config.topic_prefix, config.vehicle_id),
      backoff(config.reconnect_min, config.reconnect_max,
              config.jitter_seed != 0 ? config.jitter_seed : std::random_device{}()),
      refusal_backoff(config.reconnect_min, config.reconnect_max,
                      config.jitter_seed != 0 ? config.jitter_seed + 1 : std::random_device{}()),
      connect_listener(events),
      publish_listener(events),
      subscribe_listener(events),
      client(make_client()) {
  batch_delay = config.telemetry_batch_max_delay;
  if (config.protocol == MqttProtocol::kV5) envelope_props = envelope_properties();
}

std::unique_ptr<mqtt::async_client> Uplink::Impl::make_client() {
  auto c = uplink::make_client(normalise_broker_uri(config.broker_uri), config.vehicle_id,
                               config.protocol);
  c->set_connection_lost_handler(
      [this](const std::string& cause) { events.push(detail::ConnectionLost{cause}); });
  c->set_message_callback([this](mqtt::const_message_ptr msg) { on_message(*msg); });
  return c;
}

// Paho C reads every packet into one buffer that grows to the largest packet received and is
// freed only when its last client is destroyed: after a 20 MB message on `cmd`, 20 MB stay
// resident for good. Replacing the client (a clean disconnect and a reconnect on the persistent
// session) returns it. Publishes in flight are forgotten: their records stay in the outbox and
// are sent again (duplicates at worst, never a loss).
void Uplink::Impl::recycle_client(Micros now) {
  recycle_due = Micros{0};
  last_recycle = now;
  spdlog::info("uplink: replacing the MQTT client to release the buffer of an oversized message");
  try {
    client->disable_callbacks();
    if (client->is_connected()) client->disconnect(0)->wait_for(std::chrono::seconds(1));
  } catch (const mqtt::exception& e) {
    spdlog::debug("uplink: disconnect before replacing the client: {}", e.what());
  }
  client.reset();
  client = make_client();
  in_flight.clear();
  claimed.clear();
  forget_refused();
  batch = PendingBatch{};
  heap_trim_due = now + kTrimDelay;
  connect(now);
}

// ---- Paho thread ----
void Uplink::Impl::on_message(const mqtt::message& msg) {
  if (msg.get_topic() != topics.cmd) {
    on_zone_message(msg);
    return;
  }
  // By reference: an oversized payload is never copied, only measured (uplink_commands.cc).
  const auto& payload = msg.get_payload_ref();
  detail::triage_command({payload.data(), payload.size()}, config, commands.authenticator, events);
}

// A zone bundle is judged on the owner's thread (ZoneController); here it is only measured and
// bounded, so a huge or flooding payload costs neither a copy nor unbounded memory.
void Uplink::Impl::on_zone_message(const mqtt::message& msg) {
  const std::string& topic = msg.get_topic();
  if (std::find(config.zone_topics.begin(), config.zone_topics.end(), topic) ==
      config.zone_topics.end()) {
    return;  // not subscribed to anything else
  }
  const auto& payload = msg.get_payload_ref();
  if (events.queued_zone_bundles() >= config.max_queued_zone_bundles) {
    events.push(detail::ZoneBundleDropped{topic, "zone bundle queue full"});
    return;
  }
  if (payload.size() > config.max_zone_bundle_bytes) {
    events.push(detail::ZoneBundleArrived{topic, {}, payload.size()});
    return;
  }
  events.push(detail::ZoneBundleArrived{topic, payload.str(), 0});
}

// ---- owner's thread ----
mqtt::connect_options Uplink::Impl::make_connect_options(Micros now) const {
  ConnectionSettings s;
  s.broker_uri = normalise_broker_uri(config.broker_uri);
  s.tls = config.tls;
  s.username = config.username;
  s.password = config.password;
  s.keep_alive = config.keep_alive;
  s.connect_timeout = config.connect_timeout;
  // A persistent session: the broker keeps our cmd subscription and queued commands while the
  // vehicle is offline, and Paho re-sends unacknowledged QoS 1 publishes after a reconnect.
  s.clean_session = false;
  // Our window is the real bound; Paho's only needs room for it plus status messages.
  s.max_inflight = static_cast<int>(config.max_in_flight + 8);
  s.protocol = config.protocol;
  s.session_expiry = config.session_expiry;
  mqtt::connect_options opts = uplink::make_connect_options(s);
  const std::string will = serialize_will(now);
  if (config.protocol == MqttProtocol::kV5) {
    // The will delay is a property of the will, and says how to date the loss (docs/uplink.md).
    mqtt::properties props = envelope_props;
    props.add(mqtt::property(
        mqtt::property::WILL_DELAY_INTERVAL,
        static_cast<std::int32_t>(static_cast<std::uint32_t>(config.will_delay.count()))));
    props.add(mqtt::property(mqtt::property::USER_PROPERTY, std::string(kWillDelayProperty),
                             std::to_string(config.will_delay.count())));
    opts.set_will(mqtt::will_options(topics.status, will, config.qos, true, props));
  } else {
    opts.set_will_message(mqtt::message(topics.status, will, config.qos, true));
  }
  return opts;
}

void Uplink::Impl::connect(Micros now) {
  state = UplinkState::kConnecting;
  connect_started = now;
  const std::uint64_t attempt = ++connect_attempt;
  spdlog::debug("uplink: connecting to {} as {}", redact_uri(config.broker_uri), config.vehicle_id);
  if (config.tls && !config.tls->verify_server_name) {
    spdlog::warn("uplink: TLS host-name verification is OFF (tls.verify_server_name=false)");
  }
  try {
    client->connect(make_connect_options(now), detail::to_context(attempt), connect_listener);
  } catch (const mqtt::exception& e) {
    on_connect_failed(now, e.get_return_code(), e.what());
  }
}

void Uplink::Impl::on_connect_failed(Micros now, int rc, const std::string& message, int reason) {
  ++counters.connect_failures;
  schedule_reconnect(now);
  spdlog::debug("uplink: connect attempt {} failed: {}; next attempt in {} ms", connect_attempt,
                message, counters.last_backoff.count());
  // An MQTT 5 CONNACK refusal: the broker answered, so there is nothing to diagnose. Paho C
  // hands its reason code over as the token's return code (rc 135 for 0x87), or as the reason.
  if (config.protocol == MqttProtocol::kV5 && !is_refusal(reason) && is_refusal(rc)) reason = rc;
  if (is_refusal(reason)) {
    last_failure_was_tls = false;
    set_connect_error(now, connack_v5_reason(reason));
    return;
  }
  if (const auto refusal = connack_reason(rc); !refusal.empty()) {
    last_failure_was_tls = false;
    set_connect_error(now, std::string(refusal));
    return;
  }
  const auto target = probe_target(config.broker_uri, config.tls);
  if (!target) {
    set_connect_error(now, message);
    return;
  }
  if (diagnosis.joinable() && !diagnosis_done) {
    // Still diagnosing an earlier attempt: assume the same cause, so counts stay per attempt.
    if (last_failure_was_tls) ++counters.tls_failures;
    return;
  }
  diagnosis_done = false;
  const auto timeout =
      std::min<milliseconds>(duration_cast<milliseconds>(config.connect_timeout), kProbeTimeout);
  const std::uint64_t attempt = connect_attempt;
  std::string paho_message = message;
  diagnosis = env.start_thread("fleetgw-diagnose", [this, t = *target, timeout, attempt,
                                                    paho_message](std::stop_token) {
    std::string reason = diagnose_connect(t, timeout);
    if (reason.empty()) {
      reason = "connect failed (" + paho_message + ") although the broker " +
               (t.tls ? "completed a verified TLS handshake" : "accepts TCP connections");
    }
    events.push(detail::ConnectDiagnosed{attempt, std::move(reason)});
  });
}

void Uplink::Impl::handle(Micros now, detail::ConnectDiagnosed& e) {
  diagnosis_done = true;
  if (state == UplinkState::kConnected) return;  // connected meanwhile: no longer news
  last_failure_was_tls = is_tls_failure(e.reason);
  if (last_failure_was_tls) ++counters.tls_failures;
  set_connect_error(now, e.reason);
}

void Uplink::Impl::set_connect_error(Micros now, const std::string& reason) {
  counters.last_connect_error = reason;
  counters.last_connect_error_us = now.count();
  if (reason == logged_connect_error) return;
  logged_connect_error = reason;
  spdlog::warn("uplink: cannot connect to {}: {} (retrying with back-off, next in {} ms)",
               redact_uri(config.broker_uri), reason, counters.last_backoff.count());
}

void Uplink::Impl::schedule_reconnect(Micros now) {
  state = UplinkState::kWaitingToReconnect;
  counters.last_backoff = backoff.next();
  counters.next_connect_at_us = now.count() + counters.last_backoff.count() * 1000;
}

void Uplink::Impl::on_connected(Micros now) {
  state = UplinkState::kConnected;
  connected_at = now;
  backoff.reset();
  ++counters.connects;
  if (counters.connects > 1) ++counters.reconnects;
  counters.last_connect_error.clear();
  counters.last_connect_error_us = 0;
  logged_connect_error.clear();  // the next outage is news again
  spdlog::info("uplink: connected to {}", redact_uri(config.broker_uri));
  if (config.tcp_nodelay) {
    const auto port = broker_port(normalise_broker_uri(config.broker_uri));
    const int n = port ? enable_tcp_nodelay_to_port(*port) : 0;
    if (n == 0) spdlog::debug("uplink: no broker socket found for TCP_NODELAY");
  }
  // Tagged 0 (cmd) and n (zone_topics[n - 1]), so a refusal names its topic.
  for (std::size_t i = 0; i <= config.zone_topics.size(); ++i) {
    const std::string& topic = i == 0 ? topics.cmd : config.zone_topics[i - 1];
    try {
      client->subscribe(topic, 1, detail::to_context(i), subscribe_listener);
    } catch (const mqtt::exception& e) {
      spdlog::error("uplink: subscribe to {} failed: {}", topic, e.what());
    }
  }
  // The status handed before was built while disconnected: the owner builds a fresh one.
  status_due = false;
  status_wanted = true;
  // The broker may hold an older state (published before an outage, or by the previous run).
  vehicle_state_due = !vehicle_state.empty();
}

void Uplink::Impl::on_connection_lost(Micros now, const std::string& cause) {
  if (state != UplinkState::kConnected) return;
  ++counters.connection_losses;
  // QoS 0 publishes are not kept by Paho across a reconnect: their records become eligible
  // again (they will be re-sent, typically as QoS 1 backlog). QoS 1 publishes stay in flight:
  // Paho re-sends them on the persistent session and completes their tokens.
  for (auto it = in_flight.begin(); it != in_flight.end();) {
    if (it->second.qos == 0) {
      release(it->second.seqs);
      it = in_flight.erase(it);
    } else {
      ++it;
    }
  }
  schedule_reconnect(now);
  spdlog::warn("uplink: connection lost{}{}; next attempt in {} ms", cause.empty() ? "" : ": ",
               cause, counters.last_backoff.count());
}

void Uplink::Impl::poll(Micros now) {
  last_now = now;
  last_poll_steady = env.steady_now();
  const std::uint64_t connects_before = counters.connects;
  for (auto& ev : events.take()) {
    std::visit([&](auto& e) { handle(now, e); }, ev);
  }
  if (recycle_due.count() != 0 && now >= recycle_due &&
      (state == UplinkState::kConnected || state == UplinkState::kWaitingToReconnect)) {
    recycle_client(now);
  }
  if (heap_trim_due.count() != 0 && now >= heap_trim_due) {
    heap_trim_due = Micros{0};
    ::malloc_trim(0);
  }
  if (state == UplinkState::kWaitingToReconnect && now.count() >= counters.next_connect_at_us) {
    connect(now);
  }
  if (refusal_retry_at.count() != 0 && now >= refusal_retry_at) retry_refused(now);
  if (state == UplinkState::kConnected) {
    // The poll in which the connection came up publishes nothing: the owner first hands the
    // status of this connection (status_wanted()), which then leaves before the vehicle state
    // and the records, at the next poll (due at once).
    if (counters.connects != connects_before) {
      first_poll_due = true;
      return;
    }
    first_poll_due = false;
    resend_stale(now);
    if (status_due) publish_status(now);
    if (vehicle_state_due) publish_vehicle_state(now, true);
    drain(now);
  }
}

void Uplink::Impl::handle(Micros now, detail::ConnectDone& e) {
  if (e.attempt != connect_attempt || state != UplinkState::kConnecting) return;
  if (e.ok) {
    on_connected(now);
  } else {
    on_connect_failed(now, e.rc, e.message, e.reason);
  }
}
void Uplink::Impl::handle(Micros now, detail::ConnectionLost& e) {
  on_connection_lost(now, e.cause);
}
void Uplink::Impl::handle(Micros now, detail::PublishDone& e) {
  on_publish_done(now, e);
}
void Uplink::Impl::handle(Micros, detail::SubscribeDone& e) {
  if (e.ok) return;
  const std::string& topic =
      e.id >= 1 && e.id <= config.zone_topics.size() ? config.zone_topics[e.id - 1] : topics.cmd;
  spdlog::error("uplink: subscription to {} refused (rc {})", topic, e.rc);
}
void Uplink::Impl::handle(Micros now, detail::ZoneBundleArrived& e) {
  ++counters.zone_bundles_received;
  // The heap is trimmed after an oversized bundle, but the client is not replaced as after an
  // oversized command: the broker would deliver the retained bundle again on the new
  // connection, and the link would flap once a minute for as long as it stays retained.
  if (e.oversized_bytes >= kTrimAfterBytes && heap_trim_due.count() == 0) {
    heap_trim_due = now + kTrimDelay;
  }
  zone_bundles.push_back(
      ZoneBundleMessage{std::move(e.topic), std::move(e.payload), e.oversized_bytes});
}
void Uplink::Impl::handle(Micros, detail::ZoneBundleDropped& e) {
  ++counters.zone_bundles_dropped;
  spdlog::warn("uplink: dropped message on {}: {}", e.topic, e.reason);
}
void Uplink::Impl::handle(Micros now, detail::CommandDropped& e) {
  detail::record_drop(commands, counters, topics.cmd, now, e);
  if (e.large && recycle_due.count() == 0) {
    // At most one replacement per kRecycleInterval, so a flood cannot keep the link down.
    recycle_due = std::max(now + kTrimDelay, last_recycle + kRecycleInterval);
  }
}

void Uplink::Impl::stop(Micros now, milliseconds timeout) {
  if (state == UplinkState::kStopped) return;
  const bool was_connected = state == UplinkState::kConnected && client->is_connected();
  state = UplinkState::kStopped;
  try {
    if (was_connected) {
      // The retained state says "offline" too (a lost connection cannot: docs/uplink.md).
      if (!vehicle_state.empty()) publish_vehicle_state(now, false);
      // A clean DISCONNECT suppresses the last will, so say "offline" ourselves.
      auto tok = client->publish(make_message(
          topics.status,
          serialize_status(now, v1::ONLINE_STATE_OFFLINE, v1::CONNECTION_STATE_DISCONNECTED),
          config.qos, true));
      tok->wait_for(timeout);
      client->disconnect(static_cast<int>(timeout.count()))->wait_for(timeout);
    } else if (client->is_connected()) {
      client->disconnect(0)->wait_for(timeout);
    }
  } catch (const mqtt::exception& e) {
    spdlog::warn("uplink: error while stopping: {}", e.what());
  }
  // Records still in flight were never acked: they stay in the outbox for the next start.
  in_flight.clear();
  claimed.clear();
  forget_refused();
  batch = PendingBatch{};
  const auto leftover = events.take();
  for (const auto& ev : leftover) {
    if (std::holds_alternative<detail::ZoneBundleArrived>(ev)) events.zone_bundles_taken(1);
  }
  discard_command_events(leftover);
  events.zone_bundles_taken(zone_bundles.size());
  zone_bundles.clear();
}

Micros Uplink::Impl::next_due(Micros now) const {
  Micros due = Micros::max();
  if (state == UplinkState::kWaitingToReconnect) {
    due = std::min(due, Micros(counters.next_connect_at_us));
  }
  if (!batch.empty()) {
    due = std::min(due, Micros(batch.oldest_created_us) + duration_cast<Micros>(batch_delay));
  }
  if (state == UplinkState::kConnected && (status_due || vehicle_state_due || first_poll_due)) {
    due = now;
  }
  if (draining && !batch.empty()) due = now;
  if (state == UplinkState::kConnected) {
    const bool stale_possible = std::any_of(in_flight.begin(), in_flight.end(), [&](auto& f) {
      return f.second.connection != counters.connects;
    });
    if (stale_possible)
      due = std::min(due, connected_at + duration_cast<Micros>(config.resend_after));
  }
  if (refusal_retry_at.count() != 0) due = std::min(due, refusal_retry_at);
  if (heap_trim_due.count() != 0) due = std::min(due, heap_trim_due);
  if (recycle_due.count() != 0) due = std::min(due, recycle_due);
  return due == Micros::max() ? due : std::max(due, now);
}

// ---------------------------------------------------------------------------------------------
Uplink::Uplink(UplinkConfig config, OutboxSource& outbox, Env& env)
    : impl_(std::make_unique<Impl>(std::move(config), outbox, env)) {}

Uplink::~Uplink() {
  try {
    impl_->stop(impl_->last_now, std::chrono::seconds(2));
    impl_->client->disable_callbacks();
  } catch (...) {
    // Nothing to report to from a destructor; records not acked stay in the outbox.
  }
}

void Uplink::set_wakeup(std::function<void()> wakeup) {
  impl_->events.wakeup_ = std::move(wakeup);
}
void Uplink::set_status(v1::Status status) {
  impl_->status = std::move(status);
  impl_->status_due = true;
  impl_->status_wanted = false;
}
bool Uplink::status_wanted() const {
  return impl_->status_wanted && impl_->state == UplinkState::kConnected;
}
void Uplink::drain_for_stop() {
  impl_->draining = true;
}

void Uplink::start(Micros now) {
  if (impl_->state != UplinkState::kStopped) return;
  impl_->last_now = now;
  impl_->last_poll_steady = impl_->env.steady_now();
  impl_->connect(now);
}

void Uplink::poll(Micros now) {
  impl_->poll(now);
}

std::vector<ZoneBundleMessage> Uplink::take_zone_bundles() {
  auto out = std::exchange(impl_->zone_bundles, {});
  impl_->events.zone_bundles_taken(out.size());
  return out;
}

bool Uplink::publish_direct(std::string_view kind, std::string payload, Micros now) {
  return impl_->publish_direct(kind, std::move(payload), now);
}

bool Uplink::wait_for_events(std::chrono::milliseconds max_wait) {
  return impl_->events.wait(max_wait);
}

Micros Uplink::next_poll_due(Micros now) const {
  return std::min(impl_->next_due(now), now + std::chrono::seconds(1));
}

std::optional<std::chrono::steady_clock::time_point> Uplink::next_deadline() const {
  // Due times are on the `now` timeline of poll(); the last poll anchors it to steady_clock.
  const Micros now = impl_->last_now;
  const Micros due = impl_->next_due(now);
  if (due == Micros::max()) return std::nullopt;
  return impl_->last_poll_steady + duration_cast<std::chrono::steady_clock::duration>(due - now);
}

void Uplink::stop(Micros now, std::chrono::milliseconds timeout) {
  impl_->stop(now, timeout);
}

UplinkState Uplink::state() const {
  return impl_->state;
}

UplinkStats Uplink::stats() const {
  UplinkStats s = impl_->counters;
  s.state = impl_->state;
  s.in_flight_messages = impl_->in_flight.size();
  for (const auto& [id, f] : impl_->in_flight) s.in_flight_records += f.seqs.size();
  const OutboxStats os = impl_->outbox.stats();
  s.outbox_depth = os.depth;
  s.oldest_unsent_created_us = os.oldest_created_us;
  s.refused_records = impl_->refused_held.size();
  s.refusal_retry_at_us = impl_->refusal_retry_at.count();
  return s;
}

const Topics& Uplink::topics() const {
  return impl_->topics;
}

}  // namespace fleetgw::uplink
