// One fleet-sim process: its vehicles' sessions on one epoll loop (sim_shard.h).
#include "backend/fleet_sim/sim_shard.h"

#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <signal.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <functional>
#include <memory>
#include <queue>
#include <random>
#include <stdexcept>
#include <vector>

#include "backend/fleet_sim/fleet_sim_model.h"

namespace fleetgw::fleet_sim {

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

namespace {

std::string random_store_id(std::mt19937_64& rng) {
  // Version-4 UUID layout, like the gateway's storage.store_id.
  const std::uint64_t a = rng(), b = rng();
  std::array<char, 40> buf{};
  std::snprintf(buf.data(), buf.size(), "%08x-%04x-4%03x-%04x-%012llx",
                static_cast<unsigned>(a >> 32), static_cast<unsigned>((a >> 16) & 0xffff),
                static_cast<unsigned>(a & 0xfff),
                static_cast<unsigned>(0x8000 | ((b >> 48) & 0x3fff)),
                static_cast<unsigned long long>(b & 0xffffffffffffULL));
  return buf.data();
}

class Fd {
 public:
  explicit Fd(int fd, const char* what) : fd_(fd) {
    if (fd_ < 0) throw std::runtime_error(std::string("fleet-sim: ") + what + " failed");
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { ::close(fd_); }
  int get() const { return fd_; }

 private:
  int fd_;
};

struct MosqDelete {
  void operator()(mosquitto* m) const { mosquitto_destroy(m); }
};

constexpr std::int64_t kSecond = 1'000'000;

class Shard {
 public:
  explicit Shard(const ShardPlan& plan);
  nlohmann::json run();

 private:
  // A message of the vehicle's outbox: queued until its PUBACK. mid 0: not handed to the
  // current session (made while offline, or the session it was sent on was lost).
  struct Pending {
    SimMessage message;
    int mid = 0;
    bool sent = false;  // handed to a session at least once
    bool held = false;  // waits for the client's unrouted_retry_at (a 0x10 answer)
  };
  enum class Link { kOff, kConnecting, kUp, kDown };
  struct Client {
    Client(Shard* s, std::size_t i, SimVehicle v, std::int64_t power_on)
        : shard(s), index(i), vehicle(std::move(v)), power_on_us(power_on) {}
    Shard* shard = nullptr;
    std::size_t index = 0;
    SimVehicle vehicle;
    std::int64_t power_on_us = 0;  // its slot in the connect ramp
    std::unique_ptr<mosquitto, MosqDelete> mosq;
    int fd = -1;  // the socket registered with epoll (-1: none)
    bool watching_write = false;
    Link link = Link::kOff;
    bool ever_up = false;
    std::int64_t retry_at = 0;
    std::int64_t backoff = kSecond;
    // Records the broker routed to nobody (PUBACK 0x10): held until this time (0: none held),
    // the wait doubling while the answers go on, as the gateway's refusal lanes do.
    std::int64_t unrouted_retry_at = 0;
    std::int64_t unrouted_backoff = kSecond;
    std::deque<Pending> outbox;
  };

  static void on_connect(mosquitto*, void* self, int rc, int, const mosquitto_property*);
  static void on_disconnect(mosquitto*, void* self, int rc, const mosquitto_property*);
  static void on_publish(mosquitto*, void* self, int mid, int rc, const mosquitto_property*);

  void start_session(Client& c, std::int64_t now);
  void sync_io(Client& c);
  void lost(Client& c, std::int64_t now);
  void send(Client& c, Pending& p);
  void retry_unrouted(Client& c, std::int64_t now);
  void enqueue(Client& c, std::vector<SimMessage> out);
  bool signalled();
  std::size_t unacknowledged() const;

  ShardPlan plan_;
  Fd epoll_;
  Fd signals_;
  std::vector<std::unique_ptr<Client>> clients_;
  bool draining_ = false;
  std::minstd_rand rng_;
  // Counters of the report.
  std::int64_t messages_ = 0, records_ = 0, bytes_ = 0, resent_ = 0, refused_ = 0, unrouted_ = 0;
  std::int64_t disconnects_ = 0, connect_failures_ = 0, connected_ = 0, stale_acks_ = 0;
  std::int64_t riding_packet_bytes_ = 0, parked_packet_bytes_ = 0;
  std::int64_t last_first_connack_us_ = 0;
};

Shard::Shard(const ShardPlan& plan)
    : plan_(plan),
      epoll_(::epoll_create1(EPOLL_CLOEXEC), "epoll_create1"),
      signals_(
          [] {
            sigset_t s;
            sigemptyset(&s);
            sigaddset(&s, SIGINT);
            sigaddset(&s, SIGTERM);
            return ::signalfd(-1, &s, SFD_NONBLOCK | SFD_CLOEXEC);
          }(),
          "signalfd") {
  rng_.seed(static_cast<unsigned>(plan_.shard) + 1);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = UINT64_MAX;  // the signalfd
  ::epoll_ctl(epoll_.get(), EPOLL_CTL_ADD, signals_.get(), &ev);

  const FleetSimOptions& o = plan_.options;
  std::mt19937_64 ids(std::random_device{}());
  for (int i = plan_.shard; i < o.vehicles; i += plan_.shards) {
    const std::string id = o.id_prefix + std::to_string(o.first_index + i);
    const std::int64_t power_on =
        plan_.start_us + static_cast<std::int64_t>(static_cast<double>(i) * 1e6 / o.connect_rate);
    auto c = std::make_unique<Client>(
        this, clients_.size(),
        SimVehicle(id, random_store_id(ids), i < plan_.riding,
                   o.seed * 7919u + static_cast<unsigned>(i), power_on, o.topic_prefix),
        power_on);
    c->mosq.reset(mosquitto_new(id.c_str(), false, c.get()));
    if (!c->mosq) throw std::runtime_error("fleet-sim: mosquitto_new failed for " + id);
    mosquitto_int_option(c->mosq.get(), MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
    mosquitto_int_option(c->mosq.get(), MOSQ_OPT_TCP_NODELAY, 1);
    mosquitto_connect_v5_callback_set(c->mosq.get(), &Shard::on_connect);
    mosquitto_disconnect_v5_callback_set(c->mosq.get(), &Shard::on_disconnect);
    mosquitto_publish_v5_callback_set(c->mosq.get(), &Shard::on_publish);
    clients_.push_back(std::move(c));
  }
}

void Shard::on_connect(mosquitto*, void* self, int rc, int, const mosquitto_property*) {
  auto& c = *static_cast<Client*>(self);
  Shard& s = *c.shard;
  if (rc != 0) {
    ++s.connect_failures_;
    return;  // the broker closes the connection; on_disconnect schedules the retry
  }
  c.link = Link::kUp;
  c.backoff = kSecond;
  if (!c.ever_up) {
    c.ever_up = true;
    ++s.connected_;
    s.last_first_connack_us_ = now_us();
  }
  // The outbox's semantics: everything not acknowledged goes out again on the new session
  // (records held for a 0x10 too: the broker that routed them to nobody may have restarted).
  c.unrouted_retry_at = 0;
  for (Pending& p : c.outbox) {
    if (p.sent) ++s.resent_;
    p.mid = 0;
    p.held = false;
    s.send(c, p);
  }
}

void Shard::on_disconnect(mosquitto*, void* self, int, const mosquitto_property*) {
  auto& c = *static_cast<Client*>(self);
  c.shard->lost(c, now_us());
}

void Shard::on_publish(mosquitto*, void* self, int mid, int rc, const mosquitto_property*) {
  auto& c = *static_cast<Client*>(self);
  const auto it = std::find_if(c.outbox.begin(), c.outbox.end(),
                               [mid](const Pending& p) { return p.mid == mid; });
  if (it == c.outbox.end()) {
    ++c.shard->stale_acks_;  // a PUBACK of a session we already re-sent past
    return;
  }
  // A refusal (reason >= 0x80, e.g. quota exceeded) leaves the message queued for the next
  // session, as the gateway's outbox does.
  if (rc >= 0x80) {
    ++c.shard->refused_;
    it->mid = 0;
    return;
  }
  // 0x10 "No matching subscribers": taken and routed to nobody (mosquitto 2.0.11 answers it
  // after a restart until a restored member of a shared subscription, e.g. the ingest's
  // $share/backend/..., has reconnected). A message with records is not
  // delivered: it is held and sent again after the client's back-off, as a gateway's outbox
  // should (the gateway's MQTT library hides the code: docs/uplink.md "Delivery guarantees");
  // a retained status or state without records is done (a later subscriber gets it anyway).
  if (rc == MQTT_RC_NO_MATCHING_SUBSCRIBERS && it->message.records > 0) {
    ++c.shard->unrouted_;
    it->mid = 0;
    it->held = true;
    if (c.unrouted_retry_at == 0) {
      std::uniform_int_distribution<std::int64_t> jitter(0, c.unrouted_backoff / 2);
      c.unrouted_retry_at = now_us() + c.unrouted_backoff + jitter(c.shard->rng_);
      c.unrouted_backoff = std::min<std::int64_t>(c.unrouted_backoff * 2, 30 * kSecond);
    }
    return;
  }
  if (it->message.records > 0) c.unrouted_backoff = kSecond;  // routed: the cause is gone
  c.outbox.erase(it);
}

// The held records' back-off passed: they go out again (and the client's newer records, which
// waited behind them, with them).
void Shard::retry_unrouted(Client& c, std::int64_t now) {
  if (c.unrouted_retry_at == 0 || now < c.unrouted_retry_at || c.link != Link::kUp) return;
  c.unrouted_retry_at = 0;
  for (Pending& p : c.outbox) {
    if (!p.held) continue;
    p.held = false;
    send(c, p);
  }
  sync_io(c);
}

void Shard::lost(Client& c, std::int64_t now) {
  if (c.link == Link::kUp && !draining_) ++disconnects_;
  c.link = Link::kDown;
  c.fd = -1;  // libmosquitto closed it: the kernel dropped it from the epoll set
  c.watching_write = false;
  for (Pending& p : c.outbox) p.mid = 0;
  // Jitter: sessions lost together (a broker restart) do not all come back in the same turn.
  std::uniform_int_distribution<std::int64_t> jitter(0, c.backoff / 2);
  c.retry_at = now + c.backoff + jitter(rng_);
  c.backoff = std::min<std::int64_t>(c.backoff * 2, 30 * kSecond);
}

void Shard::send(Client& c, Pending& p) {
  if (c.link != Link::kUp || p.mid != 0) return;
  int mid = 0;
  const int rc = mosquitto_publish_v5(c.mosq.get(), &mid, p.message.topic.c_str(),
                                      static_cast<int>(p.message.payload.size()),
                                      p.message.payload.data(), 1, p.message.retained, nullptr);
  if (rc == MOSQ_ERR_SUCCESS) {
    p.mid = mid;
    p.sent = true;
  }
}

void Shard::enqueue(Client& c, std::vector<SimMessage> out) {
  for (SimMessage& m : out) {
    bytes_ += static_cast<std::int64_t>(m.topic.size() + m.payload.size());
    const std::size_t remaining = 2 + m.topic.size() + 2 + 1 + m.payload.size();
    const std::size_t varint = remaining < 128 ? 1 : remaining < 16384 ? 2 : 3;
    (c.vehicle.riding() ? riding_packet_bytes_ : parked_packet_bytes_) +=
        static_cast<std::int64_t>(1 + varint + remaining);
    records_ += static_cast<std::int64_t>(m.records);
    ++messages_;
    // Records wait behind held ones (the gateway draws no newer record of a held kind).
    const bool hold = c.unrouted_retry_at != 0 && m.records > 0;
    c.outbox.push_back({std::move(m), 0, false, hold});
    if (!hold) send(c, c.outbox.back());
  }
  sync_io(c);
}

void Shard::start_session(Client& c, std::int64_t now) {
  int rc;
  if (c.link == Link::kOff) {
    std::string bind;
    if (plan_.source_addresses > 0) {
      // By the vehicle's index in the whole fleet (--first-index included), so fleet-sims that
      // split one fleet spread over the same addresses evenly instead of all starting at .2.
      const std::size_t fleet_index = static_cast<std::size_t>(plan_.options.first_index) +
                                      c.index * static_cast<std::size_t>(plan_.shards) +
                                      static_cast<std::size_t>(plan_.shard);
      bind = "127.0.0." +
             std::to_string(2 + fleet_index % static_cast<std::size_t>(plan_.source_addresses));
    }
    // Asynchronous, like every reconnect: a blocking connect to a broker whose accept queue is
    // full (a starved broker) would stall this loop, and with it every other session's
    // keep-alive (measured: connect() blocked for the SYN retries, the broker then dropped
    // thousands of sessions). libmosquitto's asynchronous connect takes no MQTT 5 properties,
    // so no session expiry: the vehicle subscribes to nothing, a kept session would hold
    // nothing, and its outbox (below) is what survives a lost session.
    rc = mosquitto_connect_bind_async(c.mosq.get(), plan_.host.c_str(), plan_.port,
                                      plan_.options.keepalive_s,
                                      bind.empty() ? nullptr : bind.c_str());
  } else {
    rc = mosquitto_reconnect_async(c.mosq.get());
  }
  if (rc == MOSQ_ERR_SUCCESS || rc == MOSQ_ERR_CONN_PENDING) {
    c.link = Link::kConnecting;
    sync_io(c);
  } else {
    if (connect_failures_++ == 0) {
      std::fprintf(stderr, "fleet-sim[%d]: %s cannot connect: %s (errno: %s); retrying\n",
                   plan_.shard, c.vehicle.vehicle_id().c_str(), mosquitto_strerror(rc),
                   std::strerror(errno));
    }
    c.link = c.link == Link::kOff ? Link::kOff : Link::kDown;
    c.retry_at = now + c.backoff;
    c.backoff = std::min<std::int64_t>(c.backoff * 2, 30 * kSecond);
  }
}

void Shard::sync_io(Client& c) {
  const int sock = mosquitto_socket(c.mosq.get());
  if (sock < 0 && (c.link == Link::kUp || c.link == Link::kConnecting)) {
    lost(c, now_us());  // closed without a disconnect callback
    return;
  }
  if (sock != c.fd) {
    // No EPOLL_CTL_DEL of the old descriptor: libmosquitto closed it, which removed it from the
    // set, and its number may already be another session's.
    c.fd = sock;
    c.watching_write = false;
    if (sock < 0) return;
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = c.index;
    ::epoll_ctl(epoll_.get(), EPOLL_CTL_ADD, sock, &ev);
  }
  if (c.fd < 0) return;
  const bool want = mosquitto_want_write(c.mosq.get());
  if (want != c.watching_write) {
    epoll_event ev{};
    ev.events = EPOLLIN | (want ? EPOLLOUT : 0u);
    ev.data.u64 = c.index;
    ::epoll_ctl(epoll_.get(), EPOLL_CTL_MOD, c.fd, &ev);
    c.watching_write = want;
  }
}

bool Shard::signalled() {
  signalfd_siginfo info{};
  bool any = false;
  while (::read(signals_.get(), &info, sizeof info) == sizeof info) any = true;
  return any;
}

std::size_t Shard::unacknowledged() const {
  std::size_t n = 0;
  for (const auto& c : clients_) n += c->outbox.size();
  return n;
}

nlohmann::json Shard::run() {
  const FleetSimOptions& o = plan_.options;
  const std::int64_t end = plan_.start_us + static_cast<std::int64_t>(o.duration_s * 1e6);
  std::int64_t stop_deadline = INT64_MAX;
  // Vehicles by their next due time (a min-heap), and by power-on time (the ramp, in order).
  using Due = std::pair<std::int64_t, std::size_t>;
  std::priority_queue<Due, std::vector<Due>, std::greater<>> due;
  std::size_t ramp = 0;
  std::size_t misc_next = 0;
  std::int64_t last_misc = now_us(), last_log = last_misc;
  std::array<epoll_event, 512> events{};
  for (;;) {
    std::int64_t now = now_us();
    // Stop: on the first signal or at the end, every pending batch leaves (a clean stop).
    if (now >= end) draining_ = true;
    if (draining_ && stop_deadline == INT64_MAX) {
      for (std::size_t i = 0; i < ramp; ++i) enqueue(*clients_[i], clients_[i]->vehicle.drain(now));
      stop_deadline = now + static_cast<std::int64_t>(o.stop_timeout_s * 1e6);
    }
    if (draining_ && (now >= stop_deadline || unacknowledged() == 0)) break;
    // The ramp: sessions start at their power-on slot.
    while (!draining_ && ramp < clients_.size() && clients_[ramp]->power_on_us <= now) {
      Client& c = *clients_[ramp++];
      start_session(c, now);
      due.emplace(c.vehicle.next_due(), c.index);
      if (ramp == clients_.size()) {
        std::fprintf(stderr, "fleet-sim[%d]: all %zu sessions started\n", plan_.shard, ramp);
      }
    }
    // Traffic that is due.
    while (!draining_ && !due.empty() && due.top().first <= now) {
      Client& c = *clients_[due.top().second];
      due.pop();
      enqueue(c, c.vehicle.due(now));
      due.emplace(std::max(c.vehicle.next_due(), now + 1), c.index);
    }
    // Keep-alive and reconnects: every started session at least once a second, spread over the
    // loop's turns so no turn stalls on all of them.
    const double elapsed_s = static_cast<double>(now - last_misc) / 1e6;
    auto slice =
        static_cast<std::size_t>(static_cast<double>(ramp) * std::min(1.0, elapsed_s * 1.25));
    if (slice > 0) last_misc = now;
    for (; slice > 0 && ramp > 0; --slice) {
      Client& c = *clients_[misc_next];
      misc_next = (misc_next + 1) % ramp;
      if (c.link == Link::kDown || c.link == Link::kOff) {
        if (now >= c.retry_at) start_session(c, now);
      } else {
        mosquitto_loop_misc(c.mosq.get());
        retry_unrouted(c, now);
        sync_io(c);
      }
    }
    if (now - last_log >= 10 * kSecond) {
      last_log = now;
      std::fprintf(stderr,
                   "fleet-sim[%d]: %zu started, %lld connected once, %lld messages, %zu unacked, "
                   "%lld disconnects, %lld resent, %lld unrouted\n",
                   plan_.shard, ramp, static_cast<long long>(connected_),
                   static_cast<long long>(messages_), unacknowledged(),
                   static_cast<long long>(disconnects_), static_cast<long long>(resent_),
                   static_cast<long long>(unrouted_));
    }
    // Wait for I/O, at most until the next due traffic (and 50 ms, for the misc slices).
    std::int64_t wait_us = 50'000;
    if (!due.empty()) wait_us = std::clamp<std::int64_t>(due.top().first - now, 0, wait_us);
    if (ramp < clients_.size()) {
      wait_us = std::clamp<std::int64_t>(clients_[ramp]->power_on_us - now, 0, wait_us);
    }
    const int n = ::epoll_wait(epoll_.get(), events.data(), static_cast<int>(events.size()),
                               static_cast<int>((wait_us + 999) / 1000));
    for (int k = 0; k < n; ++k) {
      const std::uint64_t id = events[static_cast<std::size_t>(k)].data.u64;
      if (id == UINT64_MAX) {
        if (signalled()) {
          if (draining_) stop_deadline = 0;  // a second signal: stop waiting for PUBACKs
          draining_ = true;
        }
        continue;
      }
      Client& c = *clients_[id];
      const int sock = mosquitto_socket(c.mosq.get());
      if (sock < 0 || sock != c.fd) continue;  // closed earlier in this turn
      const std::uint32_t ev = events[static_cast<std::size_t>(k)].events;
      if ((ev & EPOLLOUT) != 0) mosquitto_loop_write(c.mosq.get(), 16);
      if ((ev & (EPOLLIN | EPOLLERR | EPOLLHUP)) != 0 && mosquitto_socket(c.mosq.get()) >= 0) {
        mosquitto_loop_read(c.mosq.get(), 16);
      }
      sync_io(c);
    }
  }
  for (auto& c : clients_) {
    if (c->link == Link::kUp) {
      mosquitto_disconnect_v5(c->mosq.get(), MQTT_RC_NORMAL_DISCONNECTION, nullptr);
    }
  }

  nlohmann::json stores = nlohmann::json::array();
  for (const auto& c : clients_) {
    stores.push_back({{"vehicle_id", c->vehicle.vehicle_id()},
                      {"store_id", c->vehicle.store_id()},
                      {"last_sequence", c->vehicle.last_sequence()},
                      {"unacknowledged", c->outbox.size()}});
  }
  const std::int64_t ramp_s =
      last_first_connack_us_ > 0 ? last_first_connack_us_ - plan_.start_us : 0;
  return {{"vehicles", clients_.size()},
          {"connected", connected_},
          {"messages", messages_},
          {"records", records_},
          {"payload_bytes", bytes_},
          {"riding_packet_bytes", riding_packet_bytes_},
          {"parked_packet_bytes", parked_packet_bytes_},
          {"resent", resent_},
          {"refused", refused_},
          {"unrouted", unrouted_},
          {"disconnects", disconnects_},
          {"connect_failures", connect_failures_},
          {"stale_acks", stale_acks_},
          {"unacknowledged", unacknowledged()},
          {"last_connack_s", static_cast<double>(ramp_s) / 1e6},
          {"stores", stores}};
}

}  // namespace

nlohmann::json run_shard(const ShardPlan& plan) {
  Shard shard(plan);
  return shard.run();
}

}  // namespace fleetgw::fleet_sim
