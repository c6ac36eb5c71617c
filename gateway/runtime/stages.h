// The runtime's stages (runtime/stage.h) around the parts of `fleetgw run` whose own classes
// stay free of the engine: each adapter turns one part's scheduling into next_deadline()/run()
// and keeps what it produced in typed outputs that the Pipeline's routes move on.
//
//  * CoreStage: the node's bus deadlines (through the BusClock) and the listeners' idle tick.
//    A simulated bus is flushed first (frames due by now delivered before the core acts); a
//    replay's core is ticked by its frames only.
//  * RecorderStage: the group commit (urgent records at once, telemetry at its deadline or at
//    any earlier timer turn outside replays); a failed write is reported, the engine retries.
//  * UplinkStage: polls the uplink when something was stored, Paho woke it, or its deadline is
//    due; the commands, busy notices and retained documents it took wait in its outputs. The
//    StoreOutbox's delete retries (acknowledged rows a failing disk kept) are due work of it too.
//    Records handed in to be published directly (an answer the store refused) are published in
//    its run, whether each reached MQTT an output.
//  * GnssStage: gpsd's feed; owns the GNSS fault-bit policy (IoT fault 0x0004 set while the
//    position is unknown), reported as an output for the node. A refused connection or a lost
//    one is the stage's error: the engine's back-off times the reconnects (add the stage with
//    the feed's reconnect_min/max as its Backoff::Options).
//  * DeviceInfoStage: node identities heard in a burst become one DeviceInfo record.
//  * TransportStage: the CAN transport's timed work (can/timed_work.h): re-opening a lost
//    interface (a failed attempt is the stage's error, so the engine's back-off spaces them;
//    add it with the transport's retry_spacing() as its Backoff::Options) and the transmit
//    retry of a full driver queue.
//  * TimerStage: a deadline of the run itself (the duration, the live view's second).
#pragma once

#include <atomic>
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "gateway/can/paced_transport.h"
#include "gateway/can/transport.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/device_info_reporter.h"
#include "gateway/runtime/engine.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/store_outbox.h"
#include "gateway/uplink/uplink.h"

namespace fleetgw::runtime {

class CoreStage final : public Stage {
 public:
  CoreStage(GatewayCore& core, const BusClock& clock, can::PacedTransport* sim,
            const Engine& engine)
      : core_(core), clock_(clock), sim_(sim), engine_(engine) {}
  std::string_view name() const override { return "core"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;
  // A timer turn was handled (the node may have raised or cleared an alarm); reset on read.
  bool take_timer_turn() { return std::exchange(timer_turn_, false); }

 private:
  GatewayCore& core_;
  const BusClock& clock_;
  can::PacedTransport* sim_;
  const Engine& engine_;
  bool timer_turn_ = false;
};

class RecorderStage final : public Stage {
 public:
  RecorderStage(Recorder& recorder, const BusClock& clock, const Engine& engine)
      : recorder_(recorder), clock_(clock), engine_(engine) {}
  std::string_view name() const override { return "recorder"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;
  // Records were stored since the last call (the uplink has something to publish).
  bool take_stored() { return std::exchange(stored_, false); }
  std::uint64_t urgent_flushes() const { return urgent_flushes_; }

 private:
  Recorder& recorder_;
  const BusClock& clock_;
  const Engine& engine_;
  bool stored_ = false;
  std::uint64_t urgent_flushes_ = 0;
};

// The bus's state for the uplink's status: the controller's, or silent when no frame was heard
// within the node's offline timeout.
fleetgw::v1::BusState bus_state(const can::Transport& transport, const BusClock& clock,
                                Micros offline_timeout);

class UplinkStage final : public Stage {
 public:
  // `outbox` (optional): its delete retries are due work of this stage.
  UplinkStage(uplink::Uplink& uplink, Engine& engine, StoreOutbox* outbox = nullptr)
      : uplink_(uplink), engine_(engine), outbox_(outbox) {}
  std::string_view name() const override { return "uplink"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;

  // Inputs. Something was stored for the uplink (on the loop's thread).
  void stored() { publish_due_ = true; }
  bool publish_due() const { return publish_due_; }
  // Paho's threads: only a flag and one posted settle.
  void signal() {
    woken_.store(true);
    engine_.wake();
  }
  // Records to publish directly, without the outbox (Uplink::publish_direct): a command result
  // the store refused. `tag` comes back in `direct_handed`.
  struct Direct {
    std::string kind;
    std::string payload;
    std::string tag;
  };
  std::vector<Direct> direct;

  // Outputs, taken by the routes.
  std::vector<std::pair<std::string, bool>> direct_handed;  // tag, reached MQTT
  std::vector<std::string> commands;
  std::vector<uplink::BusyCommand> busy;
  std::vector<uplink::ZoneBundleMessage> bundles;
  std::uint64_t polls() const { return polls_; }

 private:
  uplink::Uplink& uplink_;
  Engine& engine_;
  StoreOutbox* outbox_;
  std::atomic<bool> woken_{false};
  bool publish_due_ = false;
  std::uint64_t polls_ = 0;
};

class GnssStage final : public Stage {
 public:
  GnssStage(gnss::GnssFeed& feed, const Engine& engine) : feed_(feed), engine_(engine) {}
  std::string_view name() const override { return "gnss"; }
  // Due at once while the feed needs a connection (the engine's back-off defers it after a
  // failure), else when the fix goes stale.
  std::optional<EngineTime> next_deadline() const override {
    if (feed_.needs_connect()) return engine_.now();
    return feed_.next_deadline();
  }
  StageRun run(EngineTime now) override;

  // Outputs: the position changed (wall time and the current fix, if any) ...
  struct Update {
    Micros wall{0};
    std::optional<gnss::Fix> position;
  };
  std::optional<Update> update;
  // ... and the node's GNSS fault bit must change to this value.
  std::optional<bool> fault;

 private:
  gnss::GnssFeed& feed_;
  const Engine& engine_;
  std::optional<bool> fault_;  // the last value handed out
};

class DeviceInfoStage final : public Stage {
 public:
  DeviceInfoStage(DeviceInfoReporter& reporter, const node::NodeRegistry& registry)
      : reporter_(reporter), registry_(registry) {}
  std::string_view name() const override { return "device_info"; }
  std::optional<EngineTime> next_deadline() const override { return std::nullopt; }
  StageRun run(EngineTime now) override;
  bool due() const { return reporter_.due(); }
  // Output: the DeviceInfo record to store.
  std::optional<storage::UplinkMessage> record;

 private:
  DeviceInfoReporter& reporter_;
  const node::NodeRegistry& registry_;
};

class TransportStage final : public Stage {
 public:
  explicit TransportStage(can::TimedWork& work) : work_(work) {}
  std::string_view name() const override { return "transport"; }
  std::optional<EngineTime> next_deadline() const override { return work_.next_deadline(); }
  StageRun run(EngineTime now) override {
    auto failed = work_.poll(now);
    if (!failed) return {};
    return {.produced = 0, .status = Status::error(StatusCode::kUnavailable, std::move(*failed))};
  }
  Backoff::Options backoff() const {
    const auto s = work_.retry_spacing();
    return {.initial = s.initial, .max = s.max};
  }

 private:
  can::TimedWork& work_;
};

class TimerStage final : public Stage {
 public:
  // Due at `first`, then every `period` (zero: once).
  TimerStage(std::string name, EngineTime first, std::chrono::steady_clock::duration period)
      : name_(std::move(name)), at_(first), period_(period) {}
  std::string_view name() const override { return name_; }
  std::optional<EngineTime> next_deadline() const override { return at_; }
  StageRun run(EngineTime now) override;
  // Output: the deadline passed since the last call.
  bool take_due() { return std::exchange(due_, false); }

 private:
  std::string name_;
  std::optional<EngineTime> at_;
  std::chrono::steady_clock::duration period_;
  bool due_ = false;
};

}  // namespace fleetgw::runtime
