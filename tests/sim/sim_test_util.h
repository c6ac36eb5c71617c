// Helpers for the simulator tests: a bus probe that reassembles and decodes every frame with the
// real protocol library, and a scripted "gateway" participant that sends requests at given
// virtual times.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gateway/sim/scenario.h"
#include "gateway/sim/virtual_bus.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"

namespace fleetgw::sim::testing {

using motinova::Micros;

inline Micros seconds(double s) {
  return Micros(static_cast<int64_t>(s * 1e6));
}

inline Scenario bundled(const std::string& name) {
  return load_scenario(bundled_scenario_dir() / (name + ".toml"));
}

struct Message {
  Micros ts{0};
  motinova::AppFrame frame;
  std::string name;  // catalogue name, "unknown" when not catalogued
  bool catalogued = false;
  bool mode_matches = true;
};

// Reassembles and decodes everything it is fed; keeps every message and every error.
class Probe final : public motinova::FrameSink {
 public:
  Probe() : rx_(motinova::ReassemblerOptions{}) {}

  void push(const motinova::CanFrame& can, Micros ts) {
    ++can_frames;
    rx_.push(can, ts, *this);
  }
  void on_frame(const motinova::AppFrame& frame, Micros ts) override {
    motinova::decode(frame, motinova::Catalogue::standard(), options, decoded_);
    Message m;
    m.ts = ts;
    m.frame = frame;
    m.name = std::string(decoded_.name());
    m.catalogued = decoded_.status == motinova::DecodeStatus::kOk;
    m.mode_matches = decoded_.mode_matches;
    messages.push_back(std::move(m));
  }
  void on_error(const motinova::ReassemblyErrorEvent& e) override { errors.push_back(e); }

  // Messages on one (ID, function), in order.
  std::vector<const Message*> on(uint16_t can_id, uint8_t function) const {
    std::vector<const Message*> out;
    for (const Message& m : messages) {
      if (m.frame.can_id == can_id && m.frame.function == function) out.push_back(&m);
    }
    return out;
  }
  // First message on (ID, function) in (from, to].
  const Message* first(uint16_t can_id, uint8_t function, Micros from,
                       Micros to = Micros::max()) const {
    for (const Message& m : messages) {
      if (m.frame.can_id == can_id && m.frame.function == function && m.ts > from && m.ts <= to) {
        return &m;
      }
    }
    return nullptr;
  }
  // Decodes a stored message again (DecodedMessage views the frame it came from).
  motinova::DecodedMessage decode(const Message& m) const {
    motinova::DecodedMessage d;
    motinova::decode(m.frame, motinova::Catalogue::standard(), options, d);
    return d;
  }

  motinova::DecodeOptions options;
  std::vector<Message> messages;
  std::vector<motinova::ReassemblyErrorEvent> errors;
  uint64_t can_frames = 0;

 private:
  motinova::Reassembler rx_;
  motinova::DecodedMessage decoded_;
};

// Registers a probe on the bus.
inline void attach(VirtualBus& bus, Probe& probe) {
  VirtualBus::Participant p;
  p.name = "probe";
  p.on_frame = [&probe](const motinova::CanFrame& f, Micros ts) { probe.push(f, ts); };
  bus.add(std::move(p));
}

// A gateway stand-in: sends scripted application frames at given virtual times.
class ScriptedGateway {
 public:
  explicit ScriptedGateway(VirtualBus& bus) : bus_(bus) {
    VirtualBus::Participant p;
    p.name = "gateway";
    p.tick = [this](Micros now) { tick(now); };
    p.next_event = [this] { return script_.empty() ? Micros::max() : script_.begin()->first; };
    id_ = bus_.add(std::move(p));
  }
  // Sends `frame` at absolute virtual time `at`.
  void at(Micros at, const motinova::AppFrame& frame) { script_.emplace(at, frame); }
  // Convenience: a read request (mode 0x11, no data) or a keyword/data write.
  static motinova::AppFrame read(uint16_t id, uint8_t function) {
    return motinova::make_frame(id, motinova::Mode::kRead, function, std::span<const uint8_t>{});
  }
  static motinova::AppFrame write(uint16_t id, uint8_t function, std::string_view ascii,
                                  motinova::Mode mode = motinova::Mode::kWrite) {
    return motinova::make_frame(id, mode, function, ascii);
  }
  static motinova::AppFrame write(uint16_t id, uint8_t function, std::vector<uint8_t> data,
                                  motinova::Mode mode = motinova::Mode::kWrite) {
    return motinova::make_frame(id, mode, function, data);
  }

 private:
  void tick(Micros now) {
    while (!script_.empty() && script_.begin()->first <= now) {
      for (const motinova::CanFrame& can : motinova::segment(script_.begin()->second)) {
        bus_.send(can, id_);
      }
      script_.erase(script_.begin());
    }
  }
  VirtualBus& bus_;
  VirtualBus::ParticipantId id_ = 0;
  std::multimap<Micros, motinova::AppFrame> script_;
};

}  // namespace fleetgw::sim::testing
