#include "gateway/uplink/uplink.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <random>
#include <set>
#include <stdexcept>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>

#include <mqtt/async_client.h>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/backoff.h"
#include "gateway/uplink/tcp_nodelay.h"

namespace fleetgw::uplink {

std::string_view to_string(LinkState state) {
  switch (state) {
    case LinkState::kStopped:
      return "stopped";
    case LinkState::kConnecting:
      return "connecting";
    case LinkState::kConnected:
      return "connected";
    case LinkState::kWaitingToReconnect:
      return "waiting_to_reconnect";
  }
  return "unknown";
}

namespace {

using std::chrono::duration_cast;
using std::chrono::milliseconds;

// Events queued by Paho threads for poll(). Plain values: nothing here refers to Paho objects.
struct ConnectDone {
  std::uint64_t attempt;
  bool ok;
  int rc;
  std::string message;
};
struct ConnectionLost {
  std::string cause;
};
struct PublishDone {
  std::uint64_t id;
  bool ok;
  int rc;
  std::string message;
};
struct SubscribeDone {
  bool ok;
  int rc;
};
struct CommandArrived {
  std::string payload;
};
struct CommandDropped {
  std::string reason;
};
using Event = std::variant<ConnectDone, ConnectionLost, PublishDone, SubscribeDone, CommandArrived,
                           CommandDropped>;

// The only state shared with Paho threads.
class EventQueue {
 public:
  void push(Event e) {
    {
      std::lock_guard lock(mutex_);
      events_.push_back(std::move(e));
    }
    cv_.notify_one();
    if (wakeup_) wakeup_();
  }
  std::deque<Event> take() {
    std::lock_guard lock(mutex_);
    return std::exchange(events_, {});
  }
  bool wait(milliseconds max_wait) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, max_wait, [&] { return !events_.empty(); });
  }
  std::size_t queued_commands() const {
    std::lock_guard lock(mutex_);
    return static_cast<std::size_t>(std::count_if(events_.begin(), events_.end(), [](auto& e) {
      return std::holds_alternative<CommandArrived>(e);
    }));
  }
  // Set before the client starts; read-only afterwards, so no lock is needed to call it.
  std::function<void()> wakeup_;

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Event> events_;
};

// The user context of a Paho token carries our own integer id, never a pointer: completions
// are matched to publishes by id inside poll(), so a late completion for a publish we already
// gave up on is simply ignored.
void* to_context(std::uint64_t id) {
  return reinterpret_cast<void*>(static_cast<std::uintptr_t>(id));
}
std::uint64_t from_context(const mqtt::token& tok) {
  return static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(tok.get_user_context()));
}

std::string token_error(const mqtt::token& tok) {
  std::string msg = "rc " + std::to_string(tok.get_return_code());
  const std::string text = mqtt::exception::error_str(tok.get_return_code());
  if (!text.empty()) msg += " (" + text + ")";
  return msg;
}

class ConnectListener final : public mqtt::iaction_listener {
 public:
  explicit ConnectListener(EventQueue& q) : q_(q) {}
  void on_success(const mqtt::token& tok) override {
    q_.push(ConnectDone{from_context(tok), true, 0, {}});
  }
  void on_failure(const mqtt::token& tok) override {
    q_.push(ConnectDone{from_context(tok), false, tok.get_return_code(), token_error(tok)});
  }

 private:
  EventQueue& q_;
};

class PublishListener final : public mqtt::iaction_listener {
 public:
  explicit PublishListener(EventQueue& q) : q_(q) {}
  void on_success(const mqtt::token& tok) override {
    q_.push(PublishDone{from_context(tok), true, 0, {}});
  }
  void on_failure(const mqtt::token& tok) override {
    q_.push(PublishDone{from_context(tok), false, tok.get_return_code(), token_error(tok)});
  }

 private:
  EventQueue& q_;
};

class SubscribeListener final : public mqtt::iaction_listener {
 public:
  explicit SubscribeListener(EventQueue& q) : q_(q) {}
  void on_success(const mqtt::token&) override { q_.push(SubscribeDone{true, 0}); }
  void on_failure(const mqtt::token& tok) override {
    q_.push(SubscribeDone{false, tok.get_return_code()});
  }

 private:
  EventQueue& q_;
};

// Record kind -> where it goes in the Envelope and on which topic.
struct KindRoute {
  std::string_view kind;
  const std::string Topics::*topic;
  google::protobuf::MessageLite* (*body)(v1::Envelope&);
};

constexpr KindRoute kRoutes[] = {
    {kind::kRide, &Topics::ride,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_ride(); }},
    {kind::kFault, &Topics::fault,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_fault(); }},
    {kind::kPack, &Topics::pack,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_pack(); }},
    {kind::kLock, &Topics::lock,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_lock(); }},
    {kind::kInfo, &Topics::info,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_info(); }},
    {kind::kStatus, &Topics::status,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_status(); }},
    {kind::kCommandResult, &Topics::cmd_result,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_command_result(); }},
    {kind::kEviction, &Topics::eviction,
     [](v1::Envelope& e) -> google::protobuf::MessageLite* { return e.mutable_eviction(); }},
};

const KindRoute* find_route(std::string_view kind) {
  for (const auto& r : kRoutes) {
    if (r.kind == kind) return &r;
  }
  return nullptr;
}

std::string normalise_uri(const std::string& uri) {
  // Paho spells the schemes tcp:// and ssl://; accept the common mqtt:// and mqtts:// too.
  if (uri.rfind("mqtts://", 0) == 0) return "ssl://" + uri.substr(8);
  if (uri.rfind("mqtt://", 0) == 0) return "tcp://" + uri.substr(7);
  return uri;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
struct Uplink::Impl {
  struct PendingBatch {
    v1::TelemetryBatch batch;
    std::vector<std::uint64_t> seqs;
    std::size_t bytes = 0;
    std::int64_t oldest_created_us = 0;
    std::int64_t newest_created_us = 0;
    std::int64_t first_created_us = 0;
    bool empty() const { return seqs.empty(); }
  };

  Impl(UplinkConfig c, OutboxSource& o)
      : config((c.validate(), std::move(c))),
        outbox(o),
        topics(config.topic_prefix, config.vehicle_id),
        backoff(config.reconnect_min, config.reconnect_max,
                config.jitter_seed != 0 ? config.jitter_seed : std::random_device{}()),
        connect_listener(events),
        publish_listener(events),
        subscribe_listener(events),
        client(normalise_uri(config.broker_uri), config.vehicle_id) {
    client.set_connection_lost_handler(
        [this](const std::string& cause) { events.push(ConnectionLost{cause}); });
    client.set_message_callback([this](mqtt::const_message_ptr msg) { on_message(*msg); });
  }

  // ---- Paho thread ----
  void on_message(const mqtt::message& msg) {
    if (msg.get_topic() != topics.cmd) return;  // not subscribed to anything else
    const auto& payload = msg.get_payload_ref();
    if (payload.size() > config.max_command_bytes) {
      events.push(CommandDropped{"oversized command (" + std::to_string(payload.size()) +
                                 " bytes > " + std::to_string(config.max_command_bytes) + ")"});
      return;
    }
    v1::SignedCommand cmd;
    if (!cmd.ParseFromArray(payload.data(), static_cast<int>(payload.size())) ||
        cmd.command().empty()) {
      events.push(CommandDropped{"undecodable command (" + std::to_string(payload.size()) +
                                 " bytes, not a fleetgw.v1.SignedCommand)"});
      return;
    }
    if (events.queued_commands() >= config.max_queued_commands) {
      events.push(CommandDropped{"command queue full"});
      return;
    }
    events.push(CommandArrived{payload.str()});
  }

  // ---- caller's thread ----
  mqtt::connect_options make_connect_options(Micros now) const {
    mqtt::connect_options opts;
    opts.set_mqtt_version(MQTTVERSION_3_1_1);
    // A persistent session: the broker keeps our cmd subscription and queued commands while the
    // vehicle is offline, and Paho re-sends unacknowledged QoS 1 publishes after a reconnect.
    opts.set_clean_session(false);
    opts.set_keep_alive_interval(static_cast<int>(config.keep_alive.count()));
    opts.set_connect_timeout(static_cast<int>(config.connect_timeout.count()));
    opts.set_automatic_reconnect(false);  // our own back-off: observable and testable
    // Our window is the real bound; Paho's only needs room for it plus status messages.
    opts.set_max_inflight(static_cast<int>(config.max_in_flight + 8));
    const std::string will =
        serialize_status(now, v1::ONLINE_STATE_OFFLINE, v1::CONNECTION_STATE_LOST);
    opts.set_will_message(mqtt::message(topics.status, will, config.qos, true));
    if (!config.username.empty()) opts.set_user_name(config.username);
    if (!config.password.empty()) opts.set_password(config.password);
    if (config.tls) {
      mqtt::ssl_options ssl;
      if (!config.tls->ca_file.empty()) ssl.set_trust_store(config.tls->ca_file);
      if (!config.tls->cert_file.empty()) {
        ssl.set_key_store(config.tls->cert_file);
        ssl.set_private_key(config.tls->key_file);
      }
      ssl.set_enable_server_cert_auth(true);
      ssl.set_verify(config.tls->verify_server_name);
      ssl.set_ssl_version(MQTT_SSL_VERSION_TLS_1_2);
      // No ssl error handler: Paho C++ 1.2 keeps a pointer to the ssl_options object it was
      // set on, which does not survive the copies connect() makes (use-after-free seen under
      // ASan). A failed handshake is therefore only reported as "rc -1".
      opts.set_ssl(std::move(ssl));
    }
    return opts;
  }

  std::string serialize_status(Micros now, v1::OnlineState online, v1::ConnectionState conn) const {
    v1::Envelope env;
    fill_header(env, 0, now.count());
    auto* s = env.mutable_status();
    s->set_state(online);
    s->set_connection(conn);
    const OutboxStats os = outbox.stats();
    s->set_outbox_depth(os.depth);
    s->set_oldest_unsent_created_at_us(os.oldest_created_us);
    s->set_last_publish_ok_at_us(counters.last_publish_ok_us);
    s->set_bus_state(bus_state);
    s->set_firmware_version(config.firmware_version);
    return env.SerializeAsString();
  }

  void fill_header(v1::Envelope& env, std::uint64_t seq, std::int64_t created_us) const {
    env.set_vehicle_id(config.vehicle_id);
    env.set_sequence(seq);
    env.set_created_at_us(created_us);
    env.set_gateway_fw_version(config.firmware_version);
  }

  void connect(Micros now) {
    state = LinkState::kConnecting;
    const std::uint64_t attempt = ++connect_attempt;
    spdlog::info("uplink: connecting to {} as {}", redact_uri(config.broker_uri),
                 config.vehicle_id);
    if (config.tls && !config.tls->verify_server_name) {
      spdlog::warn("uplink: TLS host-name verification is OFF (tls.verify_server_name=false)");
    }
    try {
      client.connect(make_connect_options(now), to_context(attempt), connect_listener);
    } catch (const mqtt::exception& e) {
      on_connect_failed(now, e.what());
    }
  }

  void on_connect_failed(Micros now, const std::string& why) {
    ++counters.connect_failures;
    schedule_reconnect(now, "connect to " + redact_uri(config.broker_uri) + " failed: " + why);
  }

  void schedule_reconnect(Micros now, const std::string& why) {
    state = LinkState::kWaitingToReconnect;
    counters.last_backoff = backoff.next();
    counters.next_connect_at_us = now.count() + counters.last_backoff.count() * 1000;
    spdlog::warn("uplink: {}; next attempt in {} ms", why, counters.last_backoff.count());
  }

  void on_connected(Micros now) {
    state = LinkState::kConnected;
    connected_at = now;
    backoff.reset();
    ++counters.connects;
    if (counters.connects > 1) ++counters.reconnects;
    spdlog::info("uplink: connected to {}", redact_uri(config.broker_uri));
    if (config.tcp_nodelay) {
      const auto port = broker_port(normalise_uri(config.broker_uri));
      const int n = port ? enable_tcp_nodelay_to_port(*port) : 0;
      if (n == 0) spdlog::debug("uplink: no broker socket found for TCP_NODELAY");
    }
    try {
      client.subscribe(topics.cmd, 1, nullptr, subscribe_listener);
    } catch (const mqtt::exception& e) {
      spdlog::error("uplink: subscribe to {} failed: {}", topics.cmd, e.what());
    }
    publish_status(now);
  }

  void on_connection_lost(Micros now, const std::string& cause) {
    if (state != LinkState::kConnected) return;
    ++counters.connection_losses;
    // QoS 0 publishes are not kept by Paho across a reconnect: their records become
    // eligible again (they will be re-sent, typically as QoS 1 backlog). QoS 1 publishes stay
    // in flight: Paho re-sends them on the persistent session and completes their tokens.
    for (auto it = in_flight.begin(); it != in_flight.end();) {
      if (it->second.qos == 0) {
        release(it->second.seqs);
        it = in_flight.erase(it);
      } else {
        ++it;
      }
    }
    schedule_reconnect(now, "connection lost" + (cause.empty() ? "" : ": " + cause));
  }

  // Safety net for the persistent session: Paho normally re-sends QoS 1 publishes interrupted by
  // a connection loss and completes their tokens after the reconnect. If one is still open
  // `resend_after` into a later connection, we stop waiting for it: its records become
  // eligible again and go out in a new publish (a duplicate at worst, never a loss). A late
  // completion of the old token is ignored because its id is gone.
  void resend_stale(Micros now) {
    if (now - connected_at < duration_cast<Micros>(config.resend_after)) return;
    for (auto it = in_flight.begin(); it != in_flight.end();) {
      if (it->second.connection != counters.connects) {
        spdlog::warn(
            "uplink: publish of {} record(s) from an earlier connection never completed; "
            "sending them again",
            it->second.seqs.size());
        release(it->second.seqs);
        it = in_flight.erase(it);
      } else {
        ++it;
      }
    }
  }

  void release(const std::vector<std::uint64_t>& seqs) {
    for (const auto s : seqs) claimed.erase(s);
  }

  bool publish(const std::string& topic, std::string payload, int qos, bool retained,
               std::vector<std::uint64_t> seqs) {
    const std::uint64_t id = ++publish_id;
    const std::size_t bytes = payload.size();
    const std::size_t records = seqs.size();
    for (const auto s : seqs) claimed.insert(s);
    in_flight.emplace(id, InFlightEntry{std::move(seqs), qos, counters.connects});
    try {
      auto msg = mqtt::make_message(topic, std::move(payload), qos, retained);
      client.publish(msg, to_context(id), publish_listener);
    } catch (const mqtt::exception& e) {
      // Rejected before it left (e.g. the connection just dropped): nothing was sent, so the
      // records simply stay in the outbox.
      ++counters.failed_publishes;
      release(in_flight[id].seqs);
      in_flight.erase(id);
      spdlog::warn("uplink: publish to {} refused by the client: {}", topic, e.what());
      return false;
    }
    ++counters.published_messages;
    counters.published_records += records;
    counters.bytes_published += bytes;
    counters.in_flight_high_water = std::max(counters.in_flight_high_water, in_flight.size());
    return true;
  }

  void publish_status(Micros now) {
    publish(topics.status,
            serialize_status(now, v1::ONLINE_STATE_ONLINE, v1::CONNECTION_STATE_CONNECTED),
            config.qos, true, {});
    last_status = now;
  }

  void on_publish_done(Micros now, const PublishDone& d) {
    const auto it = in_flight.find(d.id);
    if (it == in_flight.end()) return;  // given up on earlier (QoS 0 across a connection loss)
    auto seqs = std::move(it->second.seqs);
    in_flight.erase(it);
    if (d.ok) {
      ++counters.acked_messages;
      counters.last_publish_ok_us = now.count();
      if (!seqs.empty()) {
        outbox.ack(seqs);
        counters.acked_records += seqs.size();
      }
    } else {
      ++counters.failed_publishes;
      spdlog::warn("uplink: publish of {} record(s) failed ({}); they stay in the outbox",
                   seqs.size(), d.message);
    }
    release(seqs);
  }

  void reject(const OutboxEntry& e, std::string_view why) {
    spdlog::error("uplink: dropping outbox record seq {} kind '{}' ({} bytes): {}", e.seq, e.kind,
                  e.payload.size(), why);
    ++counters.rejected_records;
    const std::uint64_t seq = e.seq;
    outbox.ack(std::span<const std::uint64_t>(&seq, 1));
  }

  std::size_t capacity() const {
    return in_flight.size() >= config.max_in_flight ? 0 : config.max_in_flight - in_flight.size();
  }

  void flush_batch(Micros now) {
    if (batch.empty()) return;
    v1::Envelope env;
    fill_header(env, batch.seqs.front(), batch.first_created_us);
    env.mutable_telemetry()->Swap(&batch.batch);
    const bool live =
        batch.newest_created_us >= now.count() - config.live_telemetry_max_age.count() * 1000;
    const int qos = live ? config.live_telemetry_qos : config.qos;
    auto seqs = std::move(batch.seqs);
    batch = PendingBatch{};
    // The records were claimed while batching; publish() claims them again (a no-op) and
    // releases them if the client refuses.
    publish(topics.telemetry, env.SerializeAsString(), qos, false, std::move(seqs));
  }

  bool batch_due(Micros now) const {
    return !batch.empty() &&
           batch.oldest_created_us + config.telemetry_batch_max_delay.count() * 1000 <= now.count();
  }

  // Adds a telemetry record to the batch; false if the window is full and it was not taken.
  bool add_telemetry(Micros now, const OutboxEntry& e) {
    v1::TelemetrySample sample;
    if (!sample.ParseFromString(e.payload)) {
      reject(e, "payload is not a fleetgw.v1.TelemetrySample");
      return true;
    }
    sample.set_sequence(e.seq);
    const std::size_t size = sample.ByteSizeLong() + 4;  // + tag and length prefix
    if (!batch.empty() && (batch.seqs.size() >= config.telemetry_batch_max_samples ||
                           batch.bytes + size > config.telemetry_batch_max_bytes)) {
      if (capacity() == 0) return false;
      flush_batch(now);
    }
    if (batch.empty()) {
      batch.first_created_us = e.created_us;
      batch.oldest_created_us = e.created_us;
      batch.newest_created_us = e.created_us;
    }
    batch.oldest_created_us = std::min(batch.oldest_created_us, e.created_us);
    batch.newest_created_us = std::max(batch.newest_created_us, e.created_us);
    *batch.batch.add_samples() = std::move(sample);
    batch.seqs.push_back(e.seq);
    batch.bytes += size;
    claimed.insert(e.seq);
    if (batch.seqs.size() >= config.telemetry_batch_max_samples) {
      if (capacity() == 0) return true;  // stays pending; flushed when the window opens
      flush_batch(now);
    }
    return true;
  }

  bool publish_record(const OutboxEntry& e) {
    const KindRoute* route = find_route(e.kind);
    if (route == nullptr) {
      reject(e, "unknown record kind");
      return true;
    }
    v1::Envelope env;
    fill_header(env, e.seq, e.created_us);
    if (!route->body(env)->ParseFromString(e.payload)) {
      reject(e, "payload does not decode as the kind's message");
      return true;
    }
    return publish(topics.*(route->topic), env.SerializeAsString(), config.qos, false, {e.seq});
  }

  void drain(Micros now) {
    if (state != LinkState::kConnected) return;
    // A full batch left pending because the window was closed goes first.
    if (!batch.empty() && capacity() > 0 &&
        (batch.seqs.size() >= config.telemetry_batch_max_samples || batch_due(now))) {
      flush_batch(now);
    }
    bool more = true;
    while (more && capacity() > 0 && state == LinkState::kConnected) {
      // One publish per free slot for ordinary records, but a whole batch per slot for
      // telemetry: fetch for telemetry only while the queue head is telemetry, so a backlog of
      // single records does not copy thousands of entries per poll.
      const std::size_t want = std::min<std::size_t>(
          head_is_telemetry ? capacity() * config.telemetry_batch_max_samples : capacity(), 4096);
      const auto entries = outbox.peek(want, config.max_fetch_bytes, claimed);
      more = entries.size() == want;
      if (entries.empty()) break;
      head_is_telemetry = entries.back().kind == kind::kTelemetry;
      for (const auto& e : entries) {
        if (claimed.contains(e.seq)) continue;  // defensive: a source ignoring `exclude`
        const bool taken = e.kind == kind::kTelemetry ? add_telemetry(now, e)
                                                      : (capacity() > 0 && publish_record(e));
        if (!taken) {
          more = false;
          break;
        }
      }
    }
    if (batch_due(now) && capacity() > 0) flush_batch(now);
  }

  void poll(Micros now) {
    last_now = now;
    for (auto& ev : events.take()) {
      std::visit([&](auto& e) { handle(now, e); }, ev);
    }
    if (state == LinkState::kWaitingToReconnect && now.count() >= counters.next_connect_at_us) {
      connect(now);
    }
    if (state == LinkState::kConnected) {
      resend_stale(now);
      if (config.status_interval.count() > 0 &&
          now - last_status >= duration_cast<Micros>(config.status_interval)) {
        publish_status(now);
      }
      drain(now);
    }
  }

  void handle(Micros now, ConnectDone& e) {
    if (e.attempt != connect_attempt || state != LinkState::kConnecting) return;
    if (e.ok) {
      on_connected(now);
    } else {
      on_connect_failed(now, e.message);
    }
  }
  void handle(Micros now, ConnectionLost& e) { on_connection_lost(now, e.cause); }
  void handle(Micros now, PublishDone& e) { on_publish_done(now, e); }
  void handle(Micros, SubscribeDone& e) {
    if (!e.ok) spdlog::error("uplink: subscription to {} refused (rc {})", topics.cmd, e.rc);
  }
  void handle(Micros, CommandArrived& e) {
    ++counters.commands_received;
    if (!command_handler) {
      received_commands.push_back(std::move(e.payload));
      return;
    }
    try {
      command_handler(e.payload);
    } catch (const std::exception& ex) {
      spdlog::error("uplink: command handler threw: {}", ex.what());
    }
  }
  void handle(Micros, CommandDropped& e) {
    ++counters.commands_dropped;
    spdlog::warn("uplink: dropped message on {}: {}", topics.cmd, e.reason);
  }

  void stop(Micros now, milliseconds timeout) {
    if (state == LinkState::kStopped) return;
    const bool was_connected = state == LinkState::kConnected && client.is_connected();
    state = LinkState::kStopped;
    try {
      if (was_connected) {
        // A clean DISCONNECT suppresses the last will, so say "offline" ourselves.
        auto tok = client.publish(mqtt::make_message(
            topics.status,
            serialize_status(now, v1::ONLINE_STATE_OFFLINE, v1::CONNECTION_STATE_DISCONNECTED),
            config.qos, true));
        tok->wait_for(timeout);
        client.disconnect(static_cast<int>(timeout.count()))->wait_for(timeout);
      } else if (client.is_connected()) {
        client.disconnect(0)->wait_for(timeout);
      }
    } catch (const mqtt::exception& e) {
      spdlog::warn("uplink: error while stopping: {}", e.what());
    }
    // Records still in flight were never acked: they stay in the outbox for the next start.
    in_flight.clear();
    claimed.clear();
    batch = PendingBatch{};
    events.take();
  }

  struct InFlightEntry {
    std::vector<std::uint64_t> seqs;  // outbox records carried; empty for status messages
    int qos = 1;
    std::uint64_t connection = 0;  // counters.connects when it was sent
  };

  UplinkConfig config;
  OutboxSource& outbox;
  Topics topics;
  Backoff backoff;
  LinkState state = LinkState::kStopped;
  UplinkStats counters;
  v1::BusState bus_state = v1::BUS_STATE_UNSPECIFIED;
  CommandHandler command_handler;
  std::vector<std::string> received_commands;  // for take_commands()
  std::uint64_t connect_attempt = 0;
  std::uint64_t publish_id = 0;
  std::unordered_map<std::uint64_t, InFlightEntry> in_flight;
  std::set<std::uint64_t> claimed;  // in flight or in the pending batch
  PendingBatch batch;
  bool head_is_telemetry = true;  // the last outbox read ended in telemetry records
  Micros last_status{0};
  Micros connected_at{0};
  Micros last_now{0};  // the latest `now` we were given (for the destructor's offline status)

  // Declared last, destroyed first: Paho may still call the listeners and the queue while the
  // client shuts down, so they must outlive it.
  EventQueue events;
  ConnectListener connect_listener;
  PublishListener publish_listener;
  SubscribeListener subscribe_listener;
  mqtt::async_client client;
};

// ---------------------------------------------------------------------------------------------
Uplink::Uplink(UplinkConfig config, OutboxSource& outbox)
    : impl_(std::make_unique<Impl>(std::move(config), outbox)) {}

Uplink::~Uplink() {
  try {
    impl_->stop(impl_->last_now, std::chrono::seconds(2));
    impl_->client.disable_callbacks();
  } catch (...) {
    // Nothing to report to from a destructor; records not acked stay in the outbox.
  }
}

void Uplink::set_command_handler(CommandHandler handler) {
  impl_->command_handler = std::move(handler);
}
void Uplink::set_wakeup(std::function<void()> wakeup) {
  impl_->events.wakeup_ = std::move(wakeup);
}
void Uplink::set_bus_state(v1::BusState state) {
  impl_->bus_state = state;
}

void Uplink::start(Micros now) {
  if (impl_->state != LinkState::kStopped) return;
  impl_->last_now = now;
  impl_->connect(now);
}

void Uplink::poll(Micros now) {
  impl_->poll(now);
}

bool Uplink::wait_for_events(std::chrono::milliseconds max_wait) {
  return impl_->events.wait(max_wait);
}

Micros Uplink::next_poll_due(Micros now) const {
  Micros due = now + std::chrono::seconds(1);
  const auto& i = *impl_;
  if (i.state == LinkState::kWaitingToReconnect) {
    due = std::min(due, Micros(i.counters.next_connect_at_us));
  }
  if (!i.batch.empty()) {
    due = std::min(due, Micros(i.batch.oldest_created_us) +
                            duration_cast<Micros>(i.config.telemetry_batch_max_delay));
  }
  if (i.state == LinkState::kConnected && i.config.status_interval.count() > 0) {
    due = std::min(due, i.last_status + duration_cast<Micros>(i.config.status_interval));
  }
  return std::max(due, now);
}

void Uplink::stop(Micros now, std::chrono::milliseconds timeout) {
  impl_->stop(now, timeout);
}

std::vector<std::string> Uplink::take_commands() {
  return std::exchange(impl_->received_commands, {});
}

bool Uplink::publish_direct(std::string_view kind, std::string payload, Micros now) {
  auto& i = *impl_;
  if (i.state != LinkState::kConnected) return false;
  const KindRoute* route = find_route(kind);
  if (route == nullptr) return false;
  v1::Envelope env;
  i.fill_header(env, 0, now.count());
  if (!route->body(env)->ParseFromString(payload)) return false;
  return i.publish(i.topics.*(route->topic), env.SerializeAsString(), i.config.qos, false, {});
}

std::optional<std::chrono::steady_clock::time_point> Uplink::next_deadline() const {
  // Interim (contract E, H-uplink owns the real one): next_poll_due on the wall clock.
  const Micros now =
      std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  if (impl_->state == LinkState::kStopped) return std::nullopt;
  // Counted from the last poll, so the deadline does not move with the clock.
  return std::chrono::steady_clock::now() + (next_poll_due(impl_->last_now) - now);
}

LinkState Uplink::state() const {
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
  return s;
}

const Topics& Uplink::topics() const {
  return impl_->topics;
}

}  // namespace fleetgw::uplink
