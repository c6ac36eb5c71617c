// Test harness for the domain trackers: a simulated bike on a VirtualBus, the real protocol
// library (Reassembler + decode) and DomainTrackers as one bus participant, ticked every 100 ms
// and flushed every 200 ms like the gateway, optionally into a real Store on a temp file. The
// gateway half can be destroyed and recreated mid-run (restart tests) while the bike rides on.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "gateway/domain/domain_trackers.h"
#include "gateway/sim/scenario.h"
#include "gateway/sim/virtual_bus.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"
#include "storage/store.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::domain::testing {

using motinova::Micros;

inline Micros secs(double s) {
  return Micros(static_cast<int64_t>(s * 1e6));
}

inline sim::Scenario bundled(const std::string& name) {
  return sim::load_scenario(sim::bundled_scenario_dir() / (name + ".toml"));
}

using fleetgw::testing::TempDir;

// Everything the trackers produced, in order (also when it went to a Store).
struct Collected {
  std::vector<storage::PendingRow<storage::RideRow>> rides;
  std::vector<storage::PendingRow<storage::FaultEventRow>> faults;
  std::vector<storage::PendingRow<storage::PackSnapshotRow>> packs;
  std::vector<storage::PendingRow<storage::TelemetryRow>> telemetry;
  std::vector<storage::PendingRow<storage::LockEventRow>> locks;
  std::vector<storage::PendingRow<storage::AlarmRow>> alarms;

  void add(const storage::Batch& b) {
    rides.insert(rides.end(), b.rides.begin(), b.rides.end());
    faults.insert(faults.end(), b.faults.begin(), b.faults.end());
    packs.insert(packs.end(), b.packs.begin(), b.packs.end());
    telemetry.insert(telemetry.end(), b.telemetry.begin(), b.telemetry.end());
    locks.insert(locks.end(), b.locks.begin(), b.locks.end());
    alarms.insert(alarms.end(), b.alarms.begin(), b.alarms.end());
  }
  // Closed rides (the records sent with an uplink payload).
  std::vector<storage::RideRow> closed_rides() const {
    std::vector<storage::RideRow> out;
    for (const auto& p : rides) {
      if (p.record.state == storage::RideState::kClosed) out.push_back(p.record);
    }
    return out;
  }
};

// The gateway half: reassembler, decoder, trackers, sink, optional store.
class Gateway final : public motinova::FrameSink {
 public:
  Gateway(DomainConfig config, std::optional<std::filesystem::path> db, Micros now)
      : sink_(), trackers_(std::move(config), sink_) {
    if (db) {
      store_.emplace(storage::StoreOptions{.path = db->string()});
      const std::vector<storage::RideRow> open = store_->open_rides();
      trackers_.restore(open, now);
    }
  }
  ~Gateway() override = default;

  void push(const motinova::CanFrame& can, Micros ts) { rx_.push(can, ts, *this); }
  void on_frame(const motinova::AppFrame& frame, Micros ts) override {
    motinova::decode(frame, motinova::Catalogue::standard(), options_, msg_);
    trackers_.on_message(msg_, ts);
  }
  void on_error(const motinova::ReassemblyErrorEvent&) override {}

  void tick(Micros now, Collected& out) {
    trackers_.tick(now);
    if (now - last_flush_ >= secs(0.2)) flush(now, out);
  }
  void flush(Micros now, Collected& out) {
    last_flush_ = now;
    if (sink_.empty()) return;
    storage::Batch b = sink_.take(now);
    out.add(b);
    if (store_) store_->write(b);
  }
  DomainTrackers& trackers() { return trackers_; }
  std::optional<storage::Store>& store() { return store_; }

 private:
  motinova::DecodeOptions options_;
  motinova::Reassembler rx_;
  motinova::DecodedMessage msg_;
  DomainSink sink_;
  DomainTrackers trackers_;
  std::optional<storage::Store> store_;
  Micros last_flush_{0};
};

// Bike physics as the simulation knows it, sampled every 100 ms (the truth the tests compare to).
struct Truth {
  Micros t;
  double odo_m, energy_out_wh, soc_pct;
};

class Harness {
 public:
  explicit Harness(sim::Scenario scenario, DomainConfig config = {},
                   std::optional<std::filesystem::path> db = std::nullopt)
      : bus_(std::move(scenario)), config_(std::move(config)), db_(std::move(db)) {
    start_gateway();
    sim::VirtualBus::Participant p;
    p.name = "gateway";
    p.on_frame = [this](const motinova::CanFrame& f, Micros ts) {
      if (gw_) gw_->push(f, ts);
    };
    p.tick = [this](Micros now) {
      next_tick_ = now + secs(0.1);
      const sim::BikeState s = bus_.bike().state();
      truth_.push_back({now, s.odo_m, s.energy_out_wh, s.soc_pct});
      if (gw_) gw_->tick(now, out);
    };
    p.next_event = [this] { return next_tick_; };
    bus_.add(std::move(p));
    next_tick_ = bus_.now();
  }

  void run_until_offset(double s) { bus_.run_until(bus_.start() + secs(s)); }
  Micros at(double s) const { return bus_.start() + secs(s); }
  sim::VirtualBus& bus() { return bus_; }
  Gateway* gateway() { return gw_.get(); }

  // Puts an application frame on the bus as the gateway would (so every participant hears it).
  void send(const motinova::AppFrame& frame) {
    for (const motinova::CanFrame& can : motinova::segment(frame)) bus_.send(can);
  }
  void send_keyword(uint16_t can_id, uint8_t function) {
    const motinova::MessageDesc* d = motinova::Catalogue::standard().find(can_id, function);
    ASSERT_NE(d, nullptr);
    send(motinova::MessageWriter(*d, motinova::DecodeOptions{}).frame());
  }

  // Restart: the gateway half dies (pending records flushed, as a clean stop would), frames on
  // the bus are lost until start_gateway().
  void stop_gateway() {
    if (gw_) gw_->flush(bus_.now(), out);
    gw_.reset();
  }
  void start_gateway() { gw_ = std::make_unique<Gateway>(config_, db_, bus_.now()); }

  // Truth at (the last sample at or before) t.
  Truth truth_at(Micros t) const {
    Truth best = truth_.front();
    for (const Truth& x : truth_) {
      if (x.t > t) break;
      best = x;
    }
    return best;
  }

  Collected out;

 private:
  sim::VirtualBus bus_;
  DomainConfig config_;
  std::optional<std::filesystem::path> db_;
  std::unique_ptr<Gateway> gw_;
  std::vector<Truth> truth_;
  Micros next_tick_{0};
};

}  // namespace fleetgw::domain::testing
