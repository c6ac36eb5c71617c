// libFuzzer target over the command path: payload parse and authentication, the freshness and
// replay checks, the journal lookup (a real SQLite store), pre-flight, execution on the
// simulated bike, and result creation/storage. Arbitrary bytes arrive either raw (what anyone
// on `cmd` can send) or, steered by the first byte, as a Command the harness signs with a
// trusted key -- so the fuzzer also reaches everything behind the signature check.
//
// Invariants beyond "no crash, no sanitizer report":
//  * every result serializes (valid UTF-8 everywhere) and has a one-line reason;
//  * a result with a command id is bound: command_sha256 (authentic) or payload_sha256;
//  * no frame of the IoT node's (lock actuation, MC write, SHUTDOWN) reaches the bus while a
//    payload that is rejected is handled.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/command_service.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/config/config.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/sim/virtual_bus.h"
#include "motinova/segmenter.h"
#include "storage/store.h"

namespace {

using namespace fleetgw;
using motinova::Micros;
using namespace std::chrono_literals;

constexpr const char* kVehicle = "bike-fuzz";
constexpr const char* kKeyId = "fuzz-key";

class BusSender final : public node::FrameSender {
 public:
  explicit BusSender(sim::VirtualBus& bus) : bus_(bus) {}
  void set_id(sim::VirtualBus::ParticipantId id) { id_ = id; }
  bool send(const motinova::AppFrame& frame) override {
    if (frame.can_id >= 0x760 && frame.can_id <= 0x76B) ++lock_frames;
    for (const auto& can : motinova::segment(frame)) bus_.send(can, id_);
    return true;
  }
  std::uint64_t lock_frames = 0;

 private:
  sim::VirtualBus& bus_;
  sim::VirtualBus::ParticipantId id_ = sim::VirtualBus::kExternal;
};

class Forwarder final : public runtime::MessageListener {
 public:
  command::CommandService* service = nullptr;
  void on_message(const motinova::DecodedMessage& m, Micros now) override {
    if (service != nullptr) service->on_message(m, now);
  }
  void tick(Micros now) override {
    if (service != nullptr) service->tick(now);
  }
};

void check(const v1::CommandResult& r) {
  std::string bytes;
  if (!r.SerializeToString(&bytes)) std::abort();
  if (!common::is_valid_utf8(r.reason())) std::abort();
  if (r.reason().find('\n') != std::string::npos) std::abort();
  if (!r.command_id().empty() && r.command_sha256().empty() && r.payload_sha256().empty()) {
    std::abort();
  }
  if (!r.command_sha256().empty() && r.command_sha256().size() != 32) std::abort();
}

// One gateway for the whole run (opening SQLite per input would measure SQLite, not us).
struct Harness {
  Harness()
      : dir(std::filesystem::temp_directory_path() /
            ("fleetgw-fuzz-command-" + std::to_string(getpid()))),
        key(command::Ed25519PrivateKey::generate()),
        bus(scenario()),
        sender(bus) {
    spdlog::set_level(spdlog::level::off);  // logging would dominate the time per input
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    cfg.vehicle.id = kVehicle;
    cfg.command.trusted_keys[kKeyId] = key.public_key().base64();
    cfg.protocol.lock_kinds = bus.bike().scenario().lock_kinds;
    sim::VirtualBus::Participant p;
    p.name = "gateway";
    // After the core, what the pipeline's command stage and its route do.
    p.on_frame = [this](const motinova::CanFrame& f, Micros ts) {
      core->on_can_frame(f, ts);
      settle(ts);
    };
    p.tick = [this](Micros now) {
      core->tick(now);
      settle(now);
    };
    p.next_event = [this] { return core->next_event(); };
    sender.set_id(bus.add(std::move(p)));
    store = std::make_unique<storage::Store>(storage::StoreOptions{.path = dir / "fuzz.db"});
    core = std::make_unique<runtime::GatewayCore>(cfg, sender);
    core->add_listener(forwarder);
    core->start(bus.now());
    command::CommandContext ctx{core->node(), *store, nullptr, {}, {}};
    ctx.clock_synchronised = [](Micros) { return true; };
    auto sc = command::make_command_service_config(cfg);
    sc.unauthenticated_results_per_minute = 1'000'000;  // reach the result path every time
    service = std::make_unique<command::CommandService>(sc, std::move(ctx));
    service->set_result_observer([](const v1::CommandResult& r, bool) { check(r); });
    forwarder.service = service.get();
    service->recover(bus.now());
    bus.run_for(2s);  // locks and MC heard
  }
  void settle(Micros now) {
    if (!service) return;
    if (const auto due = service->next_due(now); due && *due <= now) service->run(now);
    service->take_stored();
    for (const auto& u : service->take_unstored()) {
      v1::CommandResult r;
      if (!r.ParseFromString(u.serialized)) std::abort();
      check(r);
      service->unstored_handed(u.command_id, true);
    }
  }
  ~Harness() {
    forwarder.service = nullptr;
    service.reset();
    core.reset();
    store.reset();
    std::filesystem::remove_all(dir);
  }
  static sim::Scenario scenario() {
    sim::Scenario sc;
    sc.name = "fuzz-command";
    sc.duration = Micros(100LL * 24 * 3600 * 1'000'000);
    return sc;
  }

  std::filesystem::path dir;
  command::Ed25519PrivateKey key;
  config::Config cfg;
  sim::VirtualBus bus;
  BusSender sender;
  Forwarder forwarder;
  std::unique_ptr<storage::Store> store;
  std::unique_ptr<runtime::GatewayCore> core;
  std::unique_ptr<command::CommandService> service;
};

const char* const kLocks[] = {"seat", "battery", "frame", "steering", "wheel", "vehicle", ""};

const char* const kAssistNames[] = {"off", "eco", "norm", "sport", "turbo", "walk", "boost", ""};

// Makes `c` an MC command (issue 13's actions): bits 2-4 of `mode` pick the action, the rest of
// the input its value, so speed limits in and out of the MC's range, unknown assist names and
// actions mixed with a lock target all reach the service.
void set_mc_action(v1::Command& c, std::uint8_t mode, const std::string& rest) {
  const std::uint8_t value = rest.empty() ? 0 : static_cast<std::uint8_t>(rest.back());
  switch (((mode >> 2) & 0x07) % 6) {
    case 0:
      c.mutable_speed_limit()->set_kmh(value % 80);
      break;
    case 1:
      c.mutable_assist_level()->set_level(kAssistNames[value % 8]);
      break;
    case 2:
      c.mutable_headlight()->set_on((value & 1) != 0);
      break;
    case 3:
      c.mutable_clear_trip();
      break;
    case 4:
      c.mutable_power_off();
      break;
    default:
      c.mutable_speed_limit()->set_kmh(value * 1000u);
      break;  // far out of range
  }
}

// Builds the payload for this input. Byte 0 steers: bit 0 sign a Command made of the rest,
// bit 1 make it fresh and for this vehicle, bits 2-4 pick a lock kind (or, with bit 6, an MC
// action), bit 5 deliver twice.
std::string payload_of(Harness& h, const std::uint8_t* data, std::size_t size, bool& twice) {
  const std::uint8_t mode = size > 0 ? data[0] : 0;
  const std::string rest(reinterpret_cast<const char*>(data) + (size > 0 ? 1 : 0),
                         size > 0 ? size - 1 : 0);
  twice = (mode & 0x20) != 0;
  if ((mode & 0x01) == 0) return rest;
  v1::Command c;
  if (!c.ParseFromString(rest)) c.set_command_id(common::valid_utf8(rest.substr(0, 40)));
  if ((mode & 0x02) != 0) {
    const Micros now = h.bus.now();
    c.set_vehicle_id(kVehicle);
    c.set_issued_at_us(now.count());
    c.set_expires_at_us((now + 60s).count());
    if ((mode & 0x40) != 0) {
      set_mc_action(c, mode, rest);
    } else {
      if (c.action() == v1::COMMAND_ACTION_UNSPECIFIED) c.set_action(v1::COMMAND_ACTION_UNLOCK);
      const std::string_view lock = kLocks[((mode >> 2) & 0x07) % 7];
      if (lock == "vehicle") {
        c.set_whole_vehicle(true);
      } else if (!lock.empty()) {
        c.set_lock_kind(std::string(lock));
      }
    }
  }
  return command::sign_command(c, h.key, kKeyId);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Harness h;
  bool twice = false;
  const std::string payload = payload_of(h, data, size, twice);
  const std::uint64_t frames_before = h.sender.lock_frames;
  const auto d = h.service->on_payload(payload, h.bus.now());
  if (d == command::Disposition::kRejected || d == command::Disposition::kDropped) {
    if (h.sender.lock_frames != frames_before) std::abort();
  }
  if (twice) h.service->on_payload(payload, h.bus.now());
  h.bus.run_for(200ms);  // lets an accepted command progress; ticks purge and retry
  return 0;
}
