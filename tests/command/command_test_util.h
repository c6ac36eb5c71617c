// Test rig for the command service: the simulated bike on a VirtualBus, the real GatewayCore
// (reassembler -> decode -> IotNode) sending through a recording FrameSender onto the bus, a real
// SQLite Store on a temp file, DomainTrackers for lock-event causes, and a CommandService whose
// results are collected. Everything runs in lockstep on the bus's virtual timeline. After every
// frame and tick the rig does what the engine's command stage and its route do (settle()): the
// service's run(), its stored count and its unstored results taken.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/command_service.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/config/config.h"
#include "gateway/domain/domain_trackers.h"
#include "gateway/node/messages.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/sim/virtual_bus.h"
#include "motinova/segmenter.h"
#include "storage/store.h"
#include "tests/support/mosquitto_fixture.h"

namespace fleetgw::command::testing {

using motinova::Micros;
using namespace std::chrono_literals;

inline constexpr const char* kVehicle = "bike-0042";
inline constexpr const char* kKeyId = "backend-1";
// The IoT node's SHUTDOWN function code (0x760 ..., MOTINOVA-CAN.md): tests assert that a
// refused or no-op MC action never starts the shutdown procedure.
inline constexpr std::uint8_t kIotFnShutdown = 0x10;

// The wall clock, for scenarios that run against a real broker (live, not simulated time).
inline Micros wall_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
}

// Every frame the gateway put on the bus, with the virtual time.
class BusSender final : public node::FrameSender {
 public:
  struct Sent {
    motinova::AppFrame frame;
    Micros at;
  };
  explicit BusSender(sim::VirtualBus& bus) : bus_(bus) {}
  void set_id(sim::VirtualBus::ParticipantId id) { id_ = id; }
  bool send(const motinova::AppFrame& frame) override {
    sent.push_back({frame, bus_.now()});
    for (const auto& can : motinova::segment(frame)) bus_.send(can, id_);
    return true;
  }
  // LOCK (F+2) / UNLOCK (F+3) writes to lock k's command ID 0x767+k (k < 0: any lock).
  std::size_t lock_writes(int k = -1, Micros since = Micros{-1}) const {
    std::size_t n = 0;
    for (const auto& s : sent) {
      const int id = s.frame.can_id;
      if (id < 0x767 || id > 0x76B || s.at < since) continue;
      const int lock = id - 0x767;
      if (k >= 0 && lock != k) continue;
      const int f = s.frame.function - node::ids::lock_function_base(lock);
      if (f == 2 || f == 3) ++n;
    }
    return n;
  }
  // Vehicle LOCK (0x760/0x11) or UNLOCK (0x760/0x12) broadcasts.
  std::size_t vehicle_broadcasts(uint8_t function, Micros since = Micros{-1}) const {
    std::size_t n = 0;
    for (const auto& s : sent) {
      if (s.frame.can_id == 0x760 && s.frame.function == function && s.at >= since) ++n;
    }
    return n;
  }
  // Writes to the MC (0x761, mode write: 0x30 assist/light, 0x34 settings, 0x36 CLEAR; 0 = any).
  std::size_t mc_writes(uint8_t function = 0, Micros since = Micros{-1}) const {
    std::size_t n = 0;
    for (const auto& s : sent) {
      if (s.frame.can_id != 0x761 || s.frame.mode != motinova::Mode::kWrite || s.at < since) {
        continue;
      }
      if (function == 0 || s.frame.function == function) ++n;
    }
    return n;
  }
  // Frames the gateway sent with this (ID, function) since `since`.
  std::size_t frames(uint16_t can_id, uint8_t function, Micros since = Micros{-1}) const {
    std::size_t n = 0;
    for (const auto& s : sent) {
      if (s.frame.can_id == can_id && s.frame.function == function && s.at >= since) ++n;
    }
    return n;
  }
  // Anything at all to a lock ID or a vehicle LOCK/UNLOCK since `since`.
  std::size_t command_frames_since(Micros since) const {
    return lock_writes(-1, since) + vehicle_broadcasts(0x11, since) +
           vehicle_broadcasts(0x12, since);
  }

  std::vector<Sent> sent;

 private:
  sim::VirtualBus& bus_;
  sim::VirtualBus::ParticipantId id_ = sim::VirtualBus::kExternal;
};

inline sim::Scenario quiet_scenario() {
  sim::Scenario sc;
  sc.name = "command-test";
  sc.duration = Micros(3600LL * 1'000'000);
  sc.locks_locked = true;
  return sc;
}

// Feeds decoded messages to the trackers and the command service (the runtime's job).
class Forwarder final : public runtime::MessageListener {
 public:
  domain::DomainTrackers* trackers = nullptr;
  CommandService* service = nullptr;
  void on_message(const motinova::DecodedMessage& m, Micros now) override {
    if (trackers != nullptr) trackers->on_message(m, now);
    if (service != nullptr) service->on_message(m, now);
  }
  void tick(Micros now) override {
    if (trackers != nullptr) trackers->tick(now);
    if (service != nullptr) service->tick(now);
  }
};

struct Rig {
  explicit Rig(sim::Scenario scenario = quiet_scenario(), bool start_service = true)
      : dir("fleetgw-cmd-test"),
        key(Ed25519PrivateKey::generate()),
        bus(std::move(scenario)),
        sender(bus) {
    cfg.vehicle.id = kVehicle;
    cfg.command.trusted_keys[kKeyId] = key.public_key().base64();
    cfg.protocol.lock_kinds = bus.bike().scenario().lock_kinds;
    db_path = dir.path() / "fleetgw.db";
    sim::VirtualBus::Participant p;
    p.name = "gateway";
    p.on_frame = [this](const motinova::CanFrame& f, Micros ts) {
      if (!core) return;
      if (inside_core) inside_core(true);
      core->on_can_frame(f, ts);
      if (inside_core) inside_core(false);
      settle(ts);
    };
    p.tick = [this](Micros now) {
      if (!core) return;
      if (inside_core) inside_core(true);
      core->tick(now);
      if (inside_core) inside_core(false);
      settle(now);
    };
    p.next_event = [this] { return core ? core->next_event() : Micros::max(); };
    sender.set_id(bus.add(std::move(p)));
    open_store();
    make_core();
    if (start_service) make_service();
  }
  ~Rig() {
    service.reset();
    core.reset();
  }

  void open_store() {
    store = std::make_unique<storage::Store>(storage::StoreOptions{.path = db_path});
  }
  void make_core() {
    core = std::make_unique<runtime::GatewayCore>(cfg, sender);
    core->add_listener(forwarder);
    domain::DomainConfig dc;
    dc.apply(cfg.protocol);
    trackers = std::make_unique<domain::DomainTrackers>(dc, sink);
    forwarder.trackers = trackers.get();
    core->start(bus.now());
  }
  CommandServiceConfig service_config() {
    auto c = make_command_service_config(cfg);
    if (tweak) tweak(c);
    return c;
  }
  void make_service() {
    CommandContext context{core->node(), *store, trackers.get(), clock_synced, wall_clock};
    service = std::make_unique<CommandService>(service_config(), std::move(context));
    service->set_result_observer([this](const v1::CommandResult& r, bool resent) {
      results.push_back(r);
      resent_flags.push_back(resent);
    });
    forwarder.service = service.get();
  }
  // The command stage's turn and its route, as the pipeline runs them after the core: the due
  // writes, then the outputs taken (the stored count; each unstored result "published" as
  // publish_unstored_ok says).
  void settle(std::optional<Micros> now = std::nullopt) {
    if (!service || hold_stage) return;
    const Micros t = now.value_or(bus.now());
    if (const auto due = service->next_due(t); due && *due <= t) service->run(t);
    take_outputs();
  }
  void take_outputs() {
    stored_calls += static_cast<int>(service->take_stored());
    for (auto& u : service->take_unstored()) {
      unstored.push_back(std::move(u.serialized));
      service->unstored_handed(u.command_id, publish_unstored_ok);
    }
  }

  // A crash: service, node and store gone; then everything is built again on the same file.
  void restart() {
    forwarder.service = nullptr;
    service.reset();
    forwarder.trackers = nullptr;
    core.reset();
    trackers.reset();
    store.reset();
    open_store();
    make_core();
    make_service();
  }

  std::string payload(std::string_view lock, std::string_view action, std::string id = {},
                      Micros expires_in = 60s, std::optional<Micros> issued = std::nullopt) {
    const Micros now = bus.now();
    auto cmd = make_command(kVehicle, lock, action, issued.value_or(now), now + expires_in,
                            id.empty() ? random_command_id() : id);
    return sign_command(*cmd, key, kKeyId);
  }

  // An MC action (signing.h make_mc_command: "speed_limit" 15, "assist_level" eco, ...).
  std::string mc_payload(std::string_view action, std::string_view value = {}, std::string id = {},
                         Micros expires_in = 60s, std::optional<Micros> issued = std::nullopt) {
    const Micros now = bus.now();
    auto cmd = make_mc_command(kVehicle, action, value, issued.value_or(now), now + expires_in,
                               id.empty() ? random_command_id() : id);
    EXPECT_TRUE(cmd.has_value()) << action << " " << value;
    return cmd ? sign_command(*cmd, key, kKeyId) : std::string();
  }

  // The result with this id (first one), if any.
  const v1::CommandResult* result(std::string_view id) const {
    for (const auto& r : results) {
      if (r.command_id() == id) return &r;
    }
    return nullptr;
  }
  static std::string id_of(const std::string& signed_payload) {
    v1::SignedCommand s;
    s.ParseFromString(signed_payload);
    v1::Command c;
    c.ParseFromString(s.command());
    return c.command_id();
  }

  // Delivers a payload and runs the bus until its result arrives (or max_wait passes).
  const v1::CommandResult* run(const std::string& signed_payload, Micros max_wait = 10s) {
    const std::string id = id_of(signed_payload);
    const std::size_t before = results.size();
    last_disposition = service->on_payload(signed_payload, bus.now());
    take_outputs();
    const Micros until = bus.now() + max_wait;
    while (bus.now() < until) {
      for (std::size_t i = before; i < results.size(); ++i) {
        if (results[i].command_id() == id) return &results[i];
      }
      bus.run_for(10ms);
    }
    for (std::size_t i = before; i < results.size(); ++i) {
      if (results[i].command_id() == id) return &results[i];
    }
    return nullptr;
  }

  sim::LockState lock_state(int k) const {
    return bus.bike().state().lock_states[static_cast<std::size_t>(k)];
  }

  fleetgw::testing::TempDir dir;
  std::filesystem::path db_path;
  Ed25519PrivateKey key;
  config::Config cfg;
  sim::VirtualBus bus;
  BusSender sender;
  Forwarder forwarder;
  domain::DomainSink sink;
  std::unique_ptr<storage::Store> store;
  std::unique_ptr<runtime::GatewayCore> core;
  std::unique_ptr<domain::DomainTrackers> trackers;
  std::unique_ptr<CommandService> service;
  std::function<bool(Micros)> clock_synced = default_clock_synchronised;
  // Empty: the bus timeline is the wall clock (lockstep tests).
  std::function<Micros()> wall_clock;
  std::function<void(CommandServiceConfig&)> tweak;
  std::vector<v1::CommandResult> results;
  std::vector<bool> resent_flags;
  // Results the service reported stored (take_stored), and its unstored results (take_unstored).
  int stored_calls = 0;
  std::vector<std::string> unstored;
  bool publish_unstored_ok = true;
  // The test runs the service's stage itself (settle() does nothing).
  bool hold_stage = false;
  // Called with true before the core handles a frame or a tick and with false after (tests that
  // check what happens inside the transport's read handler).
  std::function<void(bool)> inside_core;
  Disposition last_disposition = Disposition::kRejected;
};

// The genuine command's bytes and id with a broken signature (what a subscriber to `cmd` can
// make from the genuine payload without the key).
inline std::string broken_copy(const std::string& genuine) {
  v1::SignedCommand s;
  s.ParseFromString(genuine);
  std::string sig = s.signature();
  sig[0] = static_cast<char>(sig[0] ^ 0x01);
  s.set_signature(sig);
  return s.SerializeAsString();
}

// Same id, different content (lock instead of unlock), a made-up signature.
inline std::string forged_other(const std::string& genuine) {
  v1::SignedCommand s;
  s.ParseFromString(genuine);
  v1::Command c;
  c.ParseFromString(s.command());
  c.set_action(v1::COMMAND_ACTION_LOCK);
  s.set_command(c.SerializeAsString());
  s.set_signature(std::string(64, 'x'));
  return s.SerializeAsString();
}

inline std::string reason_code(const v1::CommandResult& r) {
  return r.reason().substr(0, r.reason().find(':'));
}

}  // namespace fleetgw::command::testing
