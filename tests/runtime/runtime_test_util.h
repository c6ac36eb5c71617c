// Helpers for the runtime tests: the real GatewayCore as a participant of the simulator's
// VirtualBus (lockstep, virtual time), a bus log of every CAN frame with its sender, and small
// utilities (configs from TOML text, temp files, child processes).
#pragma once

#include "tests/support/files.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "gateway/config/config.h"
#include "gateway/node/frame_sender.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/sim/scenario.h"
#include "gateway/sim/virtual_bus.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"

extern char** environ;

namespace fleetgw::runtime::testing {

using motinova::Micros;

inline Micros ms(int64_t v) {
  return Micros(v * 1000);
}
inline Micros sec(double v) {
  return Micros(static_cast<int64_t>(v * 1e6));
}

inline std::filesystem::path source_dir() {
  return FLEETGW_SOURCE_DIR;
}
inline std::filesystem::path scenario_path(const std::string& name) {
  return source_dir() / "config" / "scenarios" / (name + ".toml");
}
inline sim::Scenario bundled(const std::string& name) {
  return sim::load_scenario(scenario_path(name));
}

// The real defaults of config/fleetgw.toml's schema, plus whatever `extra` TOML says.
inline config::Config make_config(const std::string& extra = "") {
  return config::parse_config("[log]\nlevel = \"warn\"\n" + extra, "test.toml");
}

// One CAN frame on the virtual bus, with who put it there.
struct BusFrame {
  Micros ts{0};
  motinova::CanFrame frame;
  bool from_gateway = false;
};

// One application frame as seen by an independent decoder on the bus.
struct BusMessage {
  Micros ts{0};
  motinova::AppFrame frame;
  bool from_gateway = false;  // ID in 0x760..0x76F (node 6 is the gateway; the sim never uses it)
};

// Independent reassembler + decoder over the whole bus (a second pair of ears).
class BusProbe final : public motinova::FrameSink {
 public:
  explicit BusProbe(motinova::CrcOrder order = motinova::CrcOrder::kBig)
      : rx_(motinova::ReassemblerOptions{.crc_order = order}) {}
  void push(const motinova::CanFrame& f, Micros ts) { rx_.push(f, ts, *this); }
  void on_frame(const motinova::AppFrame& frame, Micros ts) override {
    messages.push_back({ts, frame, (frame.can_id & 0xFF0) == 0x760});
  }
  void on_error(const motinova::ReassemblyErrorEvent& e) override { errors.push_back(e); }

  std::vector<const BusMessage*> on(uint16_t can_id, uint8_t function) const {
    std::vector<const BusMessage*> out;
    for (const auto& m : messages) {
      if (m.frame.can_id == can_id && m.frame.function == function) out.push_back(&m);
    }
    return out;
  }
  const BusMessage* first(uint16_t can_id, uint8_t function, Micros after) const {
    for (const auto& m : messages) {
      if (m.frame.can_id == can_id && m.frame.function == function && m.ts > after) return &m;
    }
    return nullptr;
  }

  std::vector<BusMessage> messages;
  std::vector<motinova::ReassemblyErrorEvent> errors;

 private:
  motinova::Reassembler rx_;
};

// GatewayCore on a VirtualBus with the simulated bike: the core's FrameSender encodes and
// segments into the bus as a participant; the participant's on_frame/tick/next_event drive the
// core. Every frame on the bus is logged (bus_log) and decoded by an independent probe.
class SimHarness {
  class BusSender final : public node::FrameSender {
   public:
    explicit BusSender(SimHarness& h) : h_(h) {}
    bool send(const motinova::AppFrame& frame) override {
      if (h_.refuse_sends) return false;
      for (const auto& can : motinova::segment(frame, h_.config.protocol.crc_order)) {
        h_.bus.send(can, h_.gateway_id);
        h_.gateway_frames.push_back({h_.bus.now(), can, true});
      }
      h_.sent.push_back({h_.bus.now(), frame, true});
      return true;
    }

   private:
    SimHarness& h_;
  };

 public:
  SimHarness(sim::Scenario scenario, config::Config cfg)
      : config(std::move(cfg)), bus(std::move(scenario)), sender_(*this), core(config, sender_) {
    // The logger hears every frame (the bike's and the gateway's: a participant hears all but
    // its own) in bus order. Node 6 (0x760-0x76F) is the gateway; the sim never sends there.
    sim::VirtualBus::Participant log;
    log.name = "log";
    log.on_frame = [this](const motinova::CanFrame& f, Micros ts) {
      bus_log.push_back({ts, f, (f.id & 0x7F0) == 0x760});
      probe.push(f, ts);
    };
    bus.add(std::move(log));
    sim::VirtualBus::Participant gw;
    gw.name = "gateway";
    gw.on_frame = [this](const motinova::CanFrame& f, Micros ts) { core.on_can_frame(f, ts); };
    gw.tick = [this](Micros now) { core.tick(now); };
    gw.next_event = [this] { return core.next_event(); };
    gateway_id = bus.add(std::move(gw));
  }

  void start() { core.start(bus.now()); }
  void run_until(Micros t) { bus.run_until(t); }
  void run_for(Micros d) { bus.run_for(d); }
  Micros t0() const { return bus.start(); }
  Micros at(double s) const { return bus.start() + sec(s); }

  config::Config config;
  sim::VirtualBus bus;
  std::vector<BusFrame> bus_log;         // every CAN frame, bus order
  BusProbe probe;                        // every valid application frame, bus order
  std::vector<BusMessage> sent;          // what the core's sender put on the bus
  std::vector<BusFrame> gateway_frames;  // the CAN segments of `sent`, in send order
  bool refuse_sends = false;
  sim::VirtualBus::ParticipantId gateway_id = 0;

 private:
  BusSender sender_;

 public:
  GatewayCore core;
};

// Checks that on every CAN ID the segments of one message are contiguous: once a segment
// starting a message (55 AA + header) is seen, the next frames on that ID must complete it before
// another start appears. Returns a description of every violation.
inline std::vector<std::string> interleaving_violations(const std::vector<BusFrame>& log,
                                                        bool gateway_only) {
  std::map<uint32_t, std::size_t> missing;  // bytes still expected per ID
  std::vector<std::string> out;
  for (std::size_t i = 0; i < log.size(); ++i) {
    const auto& f = log[i].frame;
    if (gateway_only && (f.id & 0x7F0) != 0x760) continue;
    auto& need = missing[f.id];
    const bool start = f.len >= 6 && f.data[0] == 0x55 && f.data[1] == 0xAA;
    if (start) {
      if (need > 0) {
        std::ostringstream s;
        s << "frame " << i << " on 0x" << std::hex << f.id << std::dec << " at "
          << log[i].ts.count() << " us starts a message while " << need
          << " bytes of the previous one are missing";
        out.push_back(s.str());
      }
      const std::size_t length = f.data[3];  // LENGTH byte of the application frame (§2.1)
      const std::size_t total = length + 9;  // LENGTH + 9 bytes in all
      need = total > f.len ? total - f.len : 0;
    } else if (need > 0) {
      need = need > f.len ? need - f.len : 0;
    } else if (gateway_only) {
      std::ostringstream s;
      s << "frame " << i << " on 0x" << std::hex << f.id << std::dec
        << " is a continuation segment outside any message";
      out.push_back(s.str());
    }
  }
  return out;
}

// The suites' one temporary directory (tests/support).
using TempDir = ::fleetgw::testing::TempDir;

using ::fleetgw::testing::lines_of;
using ::fleetgw::testing::read_text_file;

}  // namespace fleetgw::runtime::testing
