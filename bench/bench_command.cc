// Command round trip benchmarks (docs/commands.md, "Figures").
//
// A lock that answers at once: LOCK 5 (node B) is not fitted in the simulated bike but played by
// InstantLock, which reports the target state in the same virtual instant it hears LOCK/UNLOCK.
// (The simulator's own locks take 300-800 ms, which is mechanics, not gateway latency.)
//
//  * BM_CommandLockstep: verify (Ed25519) + journal commit + LOCK/UNLOCK write + confirmation +
//    result commit, in lockstep on the VirtualBus (no MQTT), wall time per command.
//  * BM_CommandMqttRoundTrip: the full path on loopback: an operator-side Paho client publishes
//    the SignedCommand -> mosquitto -> real Uplink -> CommandService -> IotNode -> bus -> lock ->
//    confirmation -> result stored in the SQLite outbox -> Uplink -> mosquitto -> the operator's
//    subscriber. Median and p99 over 1,000 commands. Both ends set TCP_NODELAY as the product
//    does (uplink.tcp_nodelay, `fleetgw command`); broker_nodelay:1 is the broker as
//    deploy/mosquitto/mosquitto.conf configures it, broker_nodelay:0 mosquitto's default.
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <mqtt/async_client.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/command_service.h"
#include "gateway/command/signing.h"
#include "gateway/config/config.h"
#include "gateway/node/messages.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/store_outbox.h"
#include "gateway/sim/virtual_bus.h"
#include "gateway/uplink/tcp_nodelay.h"
#include "gateway/uplink/uplink.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"
#include "storage/store.h"
#include "tests/support/mosquitto_fixture.h"

namespace {

using namespace fleetgw;
using motinova::Micros;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr const char* kVehicle = "bench-cmd";
constexpr int kLock = 4;  // LOCK 5, node B

Micros wall_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
}

// Plays lock k: status broadcast every 500 ms, target state reported at once on a write.
class InstantLock final : public motinova::FrameSink {
 public:
  InstantLock(sim::VirtualBus& bus, int k) : bus_(bus), k_(k), rx_(motinova::ReassemblerOptions{}) {
    sim::VirtualBus::Participant p;
    p.name = "instant-lock";
    p.on_frame = [this](const motinova::CanFrame& f, Micros ts) { rx_.push(f, ts, *this); };
    p.tick = [this](Micros now) {
      status();
      next_ = now + 500ms;
    };
    p.next_event = [this] { return next_; };
    id_ = bus_.add(std::move(p));
  }
  void on_frame(const motinova::AppFrame& f, Micros) override {
    if (f.can_id != node::ids::lock_command_id(k_)) return;
    const int fn = f.function - node::ids::lock_function_base(k_);
    if (fn == 2) {
      state_ = node::lock_state::kLocked;  // LOCK
    } else if (fn == 3) {
      state_ = node::lock_state::kUnlocked;  // UNLOCK
    } else if (fn != 1) {
      return;  // only status reads (F+1) are answered otherwise
    }
    status();
  }
  void on_error(const motinova::ReassemblyErrorEvent&) override {}

 private:
  void status() {
    std::array<uint8_t, node::kLockStatusLength> data{};
    data[node::kLockStateOffset] = state_;
    const auto frame = motinova::make_frame(node::ids::lock_broadcast_id(k_),
                                            motinova::Mode::kReport, node::fn::kLockStatus, data);
    for (const auto& can : motinova::segment(frame)) bus_.send(can, id_);
  }
  sim::VirtualBus& bus_;
  int k_;
  motinova::Reassembler rx_;
  sim::VirtualBus::ParticipantId id_ = 0;
  Micros next_{0};
  uint8_t state_ = node::lock_state::kLocked;
};

class BusSender final : public node::FrameSender {
 public:
  explicit BusSender(sim::VirtualBus& bus) : bus_(bus) {}
  sim::VirtualBus::ParticipantId id = sim::VirtualBus::kExternal;
  bool send(const motinova::AppFrame& frame) override {
    for (const auto& can : motinova::segment(frame)) bus_.send(can, id);
    return true;
  }

 private:
  sim::VirtualBus& bus_;
};

sim::Scenario scenario(Micros start) {
  sim::Scenario sc;
  sc.duration = Micros(24LL * 3600 * 1'000'000);
  sc.start = start;
  sc.lock_kinds[kLock] = "";  // played by InstantLock
  return sc;
}

struct Gateway {
  explicit Gateway(Micros start)
      : dir("fleetgw-bench-cmd"),
        key(command::Ed25519PrivateKey::generate()),
        bus(scenario(start)),
        sender(bus),
        lock(bus, kLock) {
    cfg.vehicle.id = kVehicle;
    cfg.command.trusted_keys["bench"] = key.public_key().base64();
    cfg.protocol.lock_kinds[kLock] = "other";
    store = std::make_unique<storage::Store>(storage::StoreOptions{.path = dir.path() / "b.db"});
    core = std::make_unique<runtime::GatewayCore>(cfg, sender);
    sim::VirtualBus::Participant p;
    p.name = "gateway";
    // After the core, the pipeline's command stage: results concluded on the bus are written.
    p.on_frame = [this](const motinova::CanFrame& f, Micros ts) {
      core->on_can_frame(f, ts);
      if (service && service->writes_pending()) service->run(ts);
    };
    p.tick = [this](Micros now) {
      core->tick(now);
      service->tick(now);
      service->run(now);
    };
    p.next_event = [this] { return core->next_event(); };
    sender.id = bus.add(std::move(p));
    core->start(bus.now());
    service = std::make_unique<command::CommandService>(
        command::make_command_service_config(cfg),
        command::CommandContext{.node = core->node(),
                                .store = *store,
                                .trackers = nullptr,
                                .clock_synchronised = command::default_clock_synchronised,
                                .wall_clock = {}});
    service->set_result_observer([this](const v1::CommandResult& r, bool) { last = r; });
    bus.run_for(2s);  // the lock is heard: online
  }
  std::string sign(const std::string& id, bool lock_it, Micros now) {
    auto c =
        command::make_command(kVehicle, "other", lock_it ? "lock" : "unlock", now, now + 60s, id);
    return command::sign_command(*c, key, "bench");
  }

  fleetgw::testing::TempDir dir;
  command::Ed25519PrivateKey key;
  config::Config cfg;
  sim::VirtualBus bus;
  BusSender sender;
  InstantLock lock;
  std::unique_ptr<storage::Store> store;
  std::unique_ptr<runtime::GatewayCore> core;
  std::unique_ptr<command::CommandService> service;
  std::optional<v1::CommandResult> last;
};

void report(benchmark::State& state, std::vector<double>& us, std::size_t failures) {
  std::sort(us.begin(), us.end());
  if (us.empty()) return;
  state.counters["median_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[std::min(us.size() - 1, us.size() * 99 / 100)];
  state.counters["max_us"] = us.back();
  state.counters["not_succeeded"] = static_cast<double>(failures);
}

void BM_CommandLockstep(benchmark::State& state) {
  Gateway gw(Micros(1'717'228'800'000'000));
  std::vector<double> us;
  std::size_t failures = 0;
  std::uint64_t i = 0;
  for (auto _ : state) {
    const std::string id = "lockstep-" + std::to_string(i);
    const std::string payload = gw.sign(id, (i++ % 2) == 1, gw.bus.now());
    gw.last.reset();
    const auto t0 = Clock::now();
    gw.service->on_payload(payload, gw.bus.now());
    while (!gw.last || gw.last->command_id() != id) gw.bus.run_for(1ms);
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    if (gw.last->result() != v1::COMMAND_RESULT_CODE_SUCCEEDED) ++failures;
  }
  report(state, us, failures);
}
BENCHMARK(BM_CommandLockstep)->Iterations(1000)->Unit(benchmark::kMicrosecond)->UseRealTime();

class Inbox {
 public:
  void push(mqtt::const_message_ptr m) {
    {
      std::lock_guard l(mu_);
      q_.push_back(std::move(m));
    }
    cv_.notify_one();
  }
  mqtt::const_message_ptr wait_pop(Clock::time_point deadline) {
    std::unique_lock l(mu_);
    if (!cv_.wait_until(l, deadline, [this] { return !q_.empty(); })) return nullptr;
    auto m = std::move(q_.front());
    q_.pop_front();
    return m;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<mqtt::const_message_ptr> q_;
};

// The operator side runs in a child process, as the real tool does: two Paho async clients in
// one process share Paho's network threads, which adds ~45 ms per direction (measured; see
// docs/commands.md) that has nothing to do with the gateway.
struct OperatorTimes {
  double total_us = 0;
  bool succeeded = false;
};

[[noreturn]] void operator_process(const std::string& uri, const command::Ed25519PrivateKey& key,
                                   int iterations, int go_fd, int out_fd) {
  char go = 0;
  if (::read(go_fd, &go, 1) != 1) ::_exit(2);
  try {
    mqtt::async_client op(uri, "bench-operator", mqtt::create_options(MQTTVERSION_3_1_1));
    Inbox inbox;
    op.set_message_callback([&](mqtt::const_message_ptr m) { inbox.push(std::move(m)); });
    mqtt::connect_options co;
    co.set_clean_session(true);
    op.connect(co)->wait();
    op.subscribe(std::string("fleet/v1/") + kVehicle + "/cmd/result", 1)->wait();
    // As `fleetgw command` does after connecting.
    if (const auto port = uplink::broker_port(uri)) uplink::enable_tcp_nodelay_to_port(*port);
    const std::string cmd_topic = std::string("fleet/v1/") + kVehicle + "/cmd";
    for (int i = 0; i < iterations; ++i) {
      const std::string id = "rt-" + std::to_string(i);
      const Micros now = wall_now();
      auto c = command::make_command(kVehicle, "other", (i % 2) == 1 ? "lock" : "unlock", now,
                                     now + 60s, id);
      const std::string payload = command::sign_command(*c, key, "bench");
      OperatorTimes t;
      const auto t0 = Clock::now();
      op.publish(cmd_topic, payload.data(), payload.size(), 1, false);
      bool done = false;
      while (!done && Clock::now() < t0 + 10s) {
        auto m = inbox.wait_pop(t0 + 10s);
        if (!m) break;
        v1::Envelope env;
        const auto& p = m->get_payload_ref();
        if (env.ParseFromArray(p.data(), static_cast<int>(p.size())) && env.has_command_result() &&
            env.command_result().command_id() == id) {
          done = true;
          t.succeeded = env.command_result().result() == v1::COMMAND_RESULT_CODE_SUCCEEDED;
        }
      }
      t.total_us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
      if (::write(out_fd, &t, sizeof t) != static_cast<ssize_t>(sizeof t)) ::_exit(3);
    }
    op.disconnect()->wait_for(1s);
  } catch (...) {
    ::_exit(4);
  }
  ::_exit(0);
}

void BM_CommandMqttRoundTrip(benchmark::State& state) {
  const int iterations = static_cast<int>(state.max_iterations);
  fleetgw::testing::MosquittoOptions mo;
  // 1: the broker as deploy/mosquitto/mosquitto.conf configures it; 0: mosquitto's default.
  mo.tcp_nodelay = state.range(0) != 0;
  fleetgw::testing::MosquittoBroker broker(mo);
  broker.start();
  Gateway gw(wall_now());
  int go[2], out[2];
  if (::pipe(go) != 0 || ::pipe(out) != 0) {
    state.SkipWithError("pipe failed");
    return;
  }
  // Fork before any Paho client exists in this process.
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(go[1]);
    ::close(out[0]);
    operator_process(broker.uri(), gw.key, iterations, go[0], out[1]);
  }
  ::close(go[0]);
  ::close(out[1]);
  ::fcntl(out[0], F_SETFL, O_NONBLOCK);

  runtime::StoreOutbox outbox(*gw.store);
  uplink::UplinkConfig uc;
  uc.broker_uri = broker.uri();
  uc.vehicle_id = kVehicle;
  uc.firmware_version = "bench";
  uplink::Uplink link(uc, outbox);
  Clock::time_point arrived{}, answered{};
  std::vector<double> in_gateway;
  gw.service->set_result_observer([&](const v1::CommandResult& r, bool) {
    gw.last = r;
    answered = Clock::now();
    in_gateway.push_back(std::chrono::duration<double, std::micro>(answered - arrived).count());
  });
  auto step = [&] {
    const Micros now = wall_now();
    if (now > gw.bus.now()) gw.bus.run_until(now);
    link.poll(now);
    for (const auto& payload : link.take_commands()) {
      arrived = Clock::now();
      gw.service->on_payload(payload, gw.bus.now());
    }
    link.wait_for_events(1ms);
  };
  link.start(wall_now());
  const auto connect_deadline = Clock::now() + 30s;
  while (link.state() != uplink::UplinkState::kConnected && Clock::now() < connect_deadline) step();
  for (const auto end = Clock::now() + 1s; Clock::now() < end;) step();
  const char g = 1;
  (void)!::write(go[1], &g, 1);
  ::close(go[1]);

  std::vector<double> us;
  std::size_t failures = 0;
  std::string buffer;
  for (auto _ : state) {
    // One benchmark iteration = one operator command, timed by the operator process.
    OperatorTimes t;
    std::size_t have = 0;
    const auto deadline = Clock::now() + 15s;
    while (have < sizeof t && Clock::now() < deadline) {
      const ssize_t n = ::read(out[0], reinterpret_cast<char*>(&t) + have, sizeof t - have);
      if (n > 0) have += static_cast<std::size_t>(n);
      step();
    }
    if (have < sizeof t) {
      state.SkipWithError("operator process stopped answering");
      break;
    }
    us.push_back(t.total_us);
    if (!t.succeeded) ++failures;
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(out[0]);
  report(state, us, failures);
  std::sort(in_gateway.begin(), in_gateway.end());
  if (!in_gateway.empty()) {
    state.counters["gateway_median_us"] = in_gateway[in_gateway.size() / 2];
    state.counters["gateway_p99_us"] =
        in_gateway[std::min(in_gateway.size() - 1, in_gateway.size() * 99 / 100)];
  }
  link.stop(wall_now(), 2s);
}
BENCHMARK(BM_CommandMqttRoundTrip)
    ->ArgName("broker_nodelay")
    ->Arg(0)
    ->Arg(1)
    ->Iterations(1000)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
