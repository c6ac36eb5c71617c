// The worker's MQTT sessions on libmosquitto's external-loop API (mqtt_sessions.h).
#include "backend/ingest/mqtt_sessions.h"

#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <poll.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>

namespace fleetgw::ingest {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

struct MosquittoDeleter {
  void operator()(mosquitto* m) const { mosquitto_destroy(m); }
};

// Reconnecting soon and often: after a restart mosquitto 2.0.11 routes nothing to the restored
// shared subscription until one of its members is connected again, and answers the vehicles'
// publishes meanwhile with 0x10 "No matching subscribers" (dropped; a gateway on Paho C 1.3
// cannot tell, docs/backend.md "Exactly once"). Vehicles retry 0.5-1 s after the loss and then
// back off; a worker retries after 100 ms and at least every 500 ms, so it is back within half
// a second of the broker. A refused connect to a broker that is down costs next to nothing.
constexpr std::chrono::milliseconds kReconnectFirst{100};
constexpr std::chrono::milliseconds kReconnectMax{500};

struct MqttSessions::Session {
  std::size_t index = 0;
  std::string id;
  std::string filter;
  const MessageSink* sink = nullptr;
  std::unique_ptr<mosquitto, MosquittoDeleter> mosq;
  bool connecting = false;  // a connection is open, CONNACK not yet read
  bool connected = false;
  bool subscribed = false;
  bool ever_connected = false;
  bool resumed = false;
  std::size_t held = 0;
  std::size_t delivered = 0;     // messages handed to the sink, ever (the read loop's progress)
  std::uint64_t generation = 0;  // sealed with a batch being written (0: not sealed)
  bool closing = false;          // its DISCONNECT is ours: not a lost connection
  // Leaving the group (leave()): the drain probe in flight (its packet id, -1: none), the
  // messages delivered when it was sent, and whether its answer found the queue empty.
  bool leaving = false;
  int probe_mid = -1;
  std::size_t probe_delivered = 0;
  bool drained = false;
  bool flush = false;  // its queue holds the first UNSUBSCRIBE only: write it before reading on
  std::string refused;
  Clock::time_point retry_at{};
  Clock::time_point next_misc{};
  std::chrono::milliseconds backoff = kReconnectFirst;
};

namespace {

struct BrokerAddress {
  std::string host;
  int port = 1883;
  bool tls = false;
};

bool parse_broker(const std::string& uri, BrokerAddress& out, std::string& error) {
  std::string_view rest = uri;
  if (rest.starts_with("tcp://") || rest.starts_with("mqtt://")) {
    rest.remove_prefix(rest.find("://") + 3);
  } else if (rest.starts_with("ssl://") || rest.starts_with("mqtts://")) {
    rest.remove_prefix(rest.find("://") + 3);
    out.tls = true;
    out.port = 8883;
  } else {
    error = "broker URI '" + uri + "': expected tcp://, mqtt://, ssl:// or mqtts://HOST[:PORT]";
    return false;
  }
  if (const auto slash = rest.find('/'); slash != std::string_view::npos) {
    rest = rest.substr(0, slash);
  }
  std::string_view host = rest;
  if (const auto colon = rest.rfind(':');
      colon != std::string_view::npos && rest.find(']', colon) == std::string_view::npos) {
    host = rest.substr(0, colon);
    const std::string_view port = rest.substr(colon + 1);
    int p = 0;
    const auto [ptr, ec] = std::from_chars(port.data(), port.data() + port.size(), p);
    if (ec != std::errc{} || ptr != port.data() + port.size() || p < 1 || p > 65535) {
      error = "broker URI '" + uri + "': bad port";
      return false;
    }
    out.port = p;
  }
  if (host.starts_with('[') && host.ends_with(']')) host = host.substr(1, host.size() - 2);
  if (host.empty()) {
    error = "broker URI '" + uri + "': no host";
    return false;
  }
  out.host = std::string(host);
  return true;
}

// A leaving session's drain probe: an UNSUBSCRIBE of the shared filter (the first one ends
// the membership: nothing new is queued for the session; the later ones find no subscription,
// which the broker answers all the same), queued once the session holds nothing, i.e. behind
// the PUBACKs of everything it received (written by poll()). mosquitto handles a client's packets
// in order and, handling a PUBACK, queues at once the messages it releases
// (db__message_delete_outgoing), so they precede the UNSUBACK on the wire: an answer with no
// message delivered since the probe means the broker holds nothing more for the session
// (docs/backend.md "Leaving for good").
void probe(MqttSessions::Session& s) {
  if (!s.leaving || !s.connected || s.drained || s.probe_mid >= 0 || s.held > 0 ||
      s.generation != 0) {
    return;
  }
  int mid = 0;
  if (const int rc = mosquitto_unsubscribe_v5(s.mosq.get(), &mid, s.filter.c_str(), nullptr);
      rc != MOSQ_ERR_SUCCESS) {
    spdlog::error("ingest: {} unsubscribe {} failed: {}", s.id, s.filter, mosquitto_strerror(rc));
    return;
  }
  s.probe_mid = mid;
  s.probe_delivered = s.delivered;
}

void session_unsubscribed(mosquitto*, void* obj, int mid, const mosquitto_property*) {
  auto& s = *static_cast<MqttSessions::Session*>(obj);
  if (mid != s.probe_mid) return;
  s.probe_mid = -1;
  s.subscribed = false;
  if (s.delivered == s.probe_delivered) s.drained = true;
}

void session_connected(mosquitto* m, void* obj, int rc, int flags, const mosquitto_property*) {
  auto& s = *static_cast<MqttSessions::Session*>(obj);
  s.connecting = false;
  if (rc != 0) {
    s.refused = mosquitto_reason_string(rc);
    spdlog::error("ingest: {}: the broker refused the connection: {}", s.id, s.refused);
    return;
  }
  s.connected = true;
  s.backoff = kReconnectFirst;
  if (!s.ever_connected) s.resumed = (flags & 1) != 0;  // CONNACK "session present"
  s.ever_connected = true;
  if (s.leaving) {
    // A leaving session never subscribes again: it unsubscribes at once, on every connection
    // (what the broker still holds for it is found anew). Its queue holds nothing else yet
    // (a new library object each connection): poll() writes it before reading on (flush), so
    // no new message is queued for the session while the first batch is being committed.
    s.probe_mid = -1;
    s.drained = false;
    probe(s);
    s.flush = true;
    return;
  }
  // (Re)subscribe on every connection: a no-op on a resumed session, needed after it expired.
  // Retained messages (every vehicle's latest status and state) go to session 1 only, and
  // only on a new subscription: every session of every restart receiving them again cost more
  // messages than the fleet's own traffic in a backlog drain. Queued like every packet: it
  // waits behind the PUBACKs of messages a resumed session delivers first.
  const int options =
      1 | (s.index == 0 ? MQTT_SUB_OPT_SEND_RETAIN_NEW : MQTT_SUB_OPT_SEND_RETAIN_NEVER);
  if (const int src = mosquitto_subscribe_v5(m, nullptr, s.filter.c_str(), 1, options, nullptr);
      src != MOSQ_ERR_SUCCESS) {
    spdlog::error("ingest: {} subscribe {} failed: {}", s.id, s.filter, mosquitto_strerror(src));
  }
}

void session_lost(mosquitto*, void* obj, int rc, const mosquitto_property*) {
  auto& s = *static_cast<MqttSessions::Session*>(obj);
  if ((s.connected || s.connecting) && !s.closing) {
    spdlog::warn(
        "ingest: {}: connection to the broker lost ({}); {} message(s) it held come "
        "again on the next connection",
        s.id, rc == 0 ? "closed" : mosquitto_strerror(rc), s.held);
  }
  s.connected = false;
  s.connecting = false;
  s.subscribed = false;
  // The PUBACKs queued on that connection die with it (the library clears its queue when it
  // connects again); the messages stay in the batch and are delivered again, DUP set.
  s.held = 0;
  s.generation = 0;
  s.retry_at = Clock::now() + s.backoff;
  s.backoff = std::min<std::chrono::milliseconds>(s.backoff * 2, kReconnectMax);
}

void session_subscribed(mosquitto*, void* obj, int, int count, const int* granted,
                        const mosquitto_property*) {
  auto& s = *static_cast<MqttSessions::Session*>(obj);
  if (count >= 1 && granted[0] < 0x80) {
    s.subscribed = true;
  } else {
    spdlog::error("ingest: {}: the broker refused the subscription to {} (reason {})", s.id,
                  s.filter, count >= 1 ? granted[0] : -1);
  }
}

void session_message(mosquitto*, void* obj, const mosquitto_message* msg,
                     const mosquitto_property*) {
  auto& s = *static_cast<MqttSessions::Session*>(obj);
  // QoS 0 has no acknowledgement to hold (the fleet publishes records at QoS 1).
  if (msg->qos > 0) ++s.held;
  ++s.delivered;
  (*s.sink)(s.index, msg->topic != nullptr ? std::string_view(msg->topic) : std::string_view(),
            std::string_view(static_cast<const char*>(msg->payload),
                             static_cast<std::size_t>(std::max(0, msg->payloadlen))));
}

// Writes what the session queued (the library writes until the socket would block).
void write_queue(MqttSessions::Session& s) {
  if (!s.mosq || mosquitto_socket(s.mosq.get()) < 0) return;
  if (mosquitto_want_write(s.mosq.get())) mosquitto_loop_write(s.mosq.get(), 1);
}

}  // namespace

namespace {

// A new library object for a session: a fresh output queue (nothing queued on a lost
// connection can ever be written on the next one).
void new_client(MqttSessions::Session& s) {
  s.mosq.reset();
  // clean_session false: a persistent session (clean start off in MQTT 5).
  s.mosq.reset(mosquitto_new(s.id.c_str(), false, &s));
  if (!s.mosq) throw std::runtime_error("ingest: mosquitto_new failed for " + s.id);
  mosquitto* m = s.mosq.get();
  mosquitto_int_option(m, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
  mosquitto_int_option(m, MOSQ_OPT_TCP_NODELAY, 1);
  // The library never writes from inside a read: every PUBACK waits for write_queue().
  mosquitto_threaded_set(m, true);
  mosquitto_connect_v5_callback_set(m, &session_connected);
  mosquitto_disconnect_v5_callback_set(m, &session_lost);
  mosquitto_subscribe_v5_callback_set(m, &session_subscribed);
  mosquitto_unsubscribe_v5_callback_set(m, &session_unsubscribed);
  mosquitto_message_v5_callback_set(m, &session_message);
}

}  // namespace

MqttSessions::MqttSessions(const IngestOptions& o, std::string client_id, MessageSink sink)
    : o_(o), client_id_(std::move(client_id)), sink_(std::move(sink)) {
  const std::size_t n = std::max<std::size_t>(1, o.sessions);
  for (std::size_t i = 0; i < n; ++i) {
    auto s = std::make_unique<Session>();
    s->index = i;
    s->id = client_id_ + "-s" + std::to_string(i + 1);
    s->filter = "$share/" + o.group + "/" + o.topic_prefix + "/#";
    s->sink = &sink_;
    sessions_.push_back(std::move(s));
  }
}

MqttSessions::~MqttSessions() = default;

bool MqttSessions::open(Session& s, std::string& error) {
  BrokerAddress addr;
  if (!parse_broker(o_.broker, addr, error)) return false;
  new_client(s);
  mosquitto* m = s.mosq.get();
  if (!o_.username.empty() || !o_.password.empty()) {
    mosquitto_username_pw_set(m, o_.username.c_str(),
                              o_.password.empty() ? nullptr : o_.password.c_str());
  }
  if (addr.tls || !o_.ca_file.empty() || !o_.cert_file.empty()) {
    // Never weakened: the chain and the host name are always verified.
    const int trc = mosquitto_tls_set(m, o_.ca_file.empty() ? nullptr : o_.ca_file.c_str(),
                                      o_.ca_file.empty() ? "/etc/ssl/certs" : nullptr,
                                      o_.cert_file.empty() ? nullptr : o_.cert_file.c_str(),
                                      o_.key_file.empty() ? nullptr : o_.key_file.c_str(), nullptr);
    if (trc != MOSQ_ERR_SUCCESS) {
      error = "TLS files: " + std::string(mosquitto_strerror(trc));
      return false;
    }
    mosquitto_tls_opts_set(m, 1 /* SSL_VERIFY_PEER */, nullptr, nullptr);
  }
  mosquitto_property* props = nullptr;
  mosquitto_property_add_int32(&props, MQTT_PROP_SESSION_EXPIRY_INTERVAL, o_.session_expiry_s);
  // How many unacknowledged messages the broker may send this session: with the batch, what
  // bounds the messages in memory.
  mosquitto_property_add_int16(
      &props, MQTT_PROP_RECEIVE_MAXIMUM,
      static_cast<std::uint16_t>(std::clamp<std::uint32_t>(o_.inflight, 1, 65535)));
  // The broker drops, instead of sending, anything bigger.
  mosquitto_property_add_int32(&props, MQTT_PROP_MAXIMUM_PACKET_SIZE, o_.max_packet_bytes);
  // Keep-alive 60 s: the broker drops a client silent for 1.5 keep-alives, so a batch held
  // through a 90 s database outage keeps its connection.
  const int rc = mosquitto_connect_bind_v5(m, addr.host.c_str(), addr.port, 60, nullptr, props);
  mosquitto_property_free_all(&props);
  if (rc != MOSQ_ERR_SUCCESS) {
    error = "cannot connect to " + o_.broker + " as " + s.id + ": " +
            (rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : mosquitto_strerror(rc));
    s.mosq.reset();
    return false;
  }
  s.connecting = true;
  s.held = 0;
  write_queue(s);  // the CONNECT
  return true;
}

bool MqttSessions::connect(std::string& error) {
  for (auto& s : sessions_) {
    if (!open(*s, error)) return false;
  }
  return true;
}

unsigned MqttSessions::poll(std::chrono::milliseconds timeout, std::span<const int> extra,
                            bool reading, const std::function<bool()>& want_more) {
  const auto now = Clock::now();
  for (auto& s : sessions_) {
    if (!s->mosq || mosquitto_socket(s->mosq.get()) < 0) {
      if (closing_ || now < s->retry_at || !s->refused.empty()) continue;
      // A new library object, so nothing queued on the lost connection is ever written.
      std::string error;
      if (!open(*s, error)) {
        spdlog::warn("ingest: {}; retrying", error);
        s->retry_at = now + s->backoff;
        s->backoff = std::min<std::chrono::milliseconds>(s->backoff * 2, kReconnectMax);
      }
      continue;
    }
    mosquitto* m = s->mosq.get();
    if (now >= s->next_misc) {
      // Keep-alive: a PINGREQ is queued when due (and written with the queue); a broker
      // silent for a keep-alive after it closes the connection.
      mosquitto_loop_misc(m);
      s->next_misc = now + 1s;
    }
  }
  std::vector<pollfd> fds;
  fds.reserve(sessions_.size() + extra.size());
  for (auto& s : sessions_) {
    const int sock = s->mosq ? mosquitto_socket(s->mosq.get()) : -1;
    short events = 0;
    if (reading && s->generation == 0) events |= POLLIN;
    if (s->held == 0 && mosquitto_want_write(s->mosq.get())) events |= POLLOUT;
    fds.push_back({events != 0 ? sock : -1, events, 0});
  }
  for (const int fd : extra) fds.push_back({fd, POLLIN, 0});
  ::poll(fds.data(), fds.size(), static_cast<int>(std::max<long long>(0, timeout.count())));
  for (std::size_t i = 0; i < sessions_.size(); ++i) {
    Session& s = *sessions_[i];
    const short rev = fds[i].revents;
    if (rev == 0 || fds[i].fd < 0) continue;
    mosquitto* m = s.mosq.get();
    if ((rev & POLLOUT) != 0 && s.held == 0) mosquitto_loop_write(m, 1);
    if (reading && s.generation == 0 && (rev & (POLLIN | POLLHUP | POLLERR)) != 0 &&
        mosquitto_socket(m) >= 0) {
      // One packet per call (the library reads a packet's header and body separately), while
      // the socket has bytes and the batch wants more; bounded so no session starves others.
      // A call that delivered no message and left EAGAIN in errno found the socket empty (the
      // library's read says so with success): the turn ends there, one failed read per turn
      // instead of a FIONREAD per message (issue 25: a system call per message less). A call
      // that delivered a message may leave EAGAIN too (the library's wake-up write of each
      // queued PUBACK fails once its socket pair is full): it does not end the turn.
      for (int k = 0; k < 4096 && want_more() && !s.flush; ++k) {
        const std::size_t delivered = s.delivered;
        errno = 0;
        if (mosquitto_loop_read(m, 1) != MOSQ_ERR_SUCCESS || mosquitto_socket(m) < 0) break;
        if (s.delivered == delivered && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      }
    }
    if (s.held == 0) write_queue(s);  // e.g. the SUBSCRIBE after a CONNACK
    s.flush = false;
  }
  for (auto& s : sessions_) probe(*s);
  unsigned ready = 0;
  for (std::size_t i = 0; i < extra.size(); ++i) {
    if ((fds[sessions_.size() + i].revents & POLLIN) != 0) ready |= 1u << i;
  }
  return ready;
}

std::size_t MqttSessions::seal(std::uint64_t generation) {
  std::size_t n = 0;
  for (auto& s : sessions_) {
    if (s->held > 0 && s->generation == 0) {
      s->generation = generation;
      ++n;
    }
  }
  return n;
}

void MqttSessions::acknowledge(std::uint64_t generation) {
  for (auto& s : sessions_) {
    if (s->generation != generation) continue;
    s->generation = 0;
    s->held = 0;
    write_queue(*s);
  }
}

void MqttSessions::acknowledge() {
  for (auto& s : sessions_) {
    s->generation = 0;
    s->held = 0;
    write_queue(*s);
  }
}

bool MqttSessions::saturated() const {
  return std::all_of(sessions_.begin(), sessions_.end(),
                     [&](const auto& s) { return s->generation != 0 || s->held >= o_.inflight; });
}

void MqttSessions::leave() {
  for (auto& s : sessions_) s->leaving = true;
}

std::size_t MqttSessions::drained() const {
  return static_cast<std::size_t>(
      std::count_if(sessions_.begin(), sessions_.end(), [](const auto& s) { return s->drained; }));
}

void MqttSessions::close(bool committed, bool forget) {
  closing_ = true;
  if (!committed) {
    // Nothing more is written: the held messages stay unacknowledged in the broker's sessions.
    for (auto& s : sessions_) s->mosq.reset();
    return;
  }
  acknowledge();
  for (auto& s : sessions_) {
    s->closing = true;
    if (s->mosq && mosquitto_socket(s->mosq.get()) >= 0) {
      // Session expiry 0 at a leave's end: the broker forgets the session at this DISCONNECT.
      mosquitto_property* props = nullptr;
      if (forget) mosquitto_property_add_int32(&props, MQTT_PROP_SESSION_EXPIRY_INTERVAL, 0);
      mosquitto_disconnect_v5(s->mosq.get(), MQTT_RC_NORMAL_DISCONNECTION, props);
      mosquitto_property_free_all(&props);
    }
  }
  // Write the DISCONNECTs (and any PUBACK still queued), a few seconds at most.
  const auto deadline = Clock::now() + 5s;
  while (Clock::now() < deadline) {
    std::vector<pollfd> fds;
    for (auto& s : sessions_) {
      const int sock = s->mosq ? mosquitto_socket(s->mosq.get()) : -1;
      if (sock >= 0 && mosquitto_want_write(s->mosq.get())) fds.push_back({sock, POLLOUT, 0});
    }
    if (fds.empty()) break;
    ::poll(fds.data(), fds.size(), 100);
    for (auto& s : sessions_) write_queue(*s);
  }
  for (auto& s : sessions_) s->mosq.reset();
}

std::size_t MqttSessions::size() const {
  return sessions_.size();
}

std::size_t MqttSessions::subscribed() const {
  return static_cast<std::size_t>(std::count_if(sessions_.begin(), sessions_.end(),
                                                [](const auto& s) { return s->subscribed; }));
}

std::size_t MqttSessions::connected() const {
  return static_cast<std::size_t>(std::count_if(sessions_.begin(), sessions_.end(),
                                                [](const auto& s) { return s->connected; }));
}

std::size_t MqttSessions::resumed() const {
  return static_cast<std::size_t>(
      std::count_if(sessions_.begin(), sessions_.end(), [](const auto& s) { return s->resumed; }));
}

std::size_t MqttSessions::held() const {
  std::size_t n = 0;
  for (const auto& s : sessions_) n += s->held;
  return n;
}

std::string MqttSessions::refused() const {
  for (const auto& s : sessions_) {
    if (!s->refused.empty()) return s->id + ": " + s->refused;
  }
  return {};
}

}  // namespace fleetgw::ingest
