// Pipeline: the WIRING of `fleetgw run`. It builds the stages -- GatewayCore (reassembly, decode,
// node), Recorder (domain trackers -> SQLite), CommandService, Uplink (outbox -> MQTT), GNSS,
// zones, parked mode, the vehicle-state throttle -- puts each behind the stage contract
// (runtime/stage.h; adapters in stages.h) and hands them to the Engine (runtime/engine.h), which
// owns the one timer, the settle loop, the wake-up from other threads and the retries. The
// pipeline declares the routes between the stages' outputs and inputs (add_stages()).
//
// Contract:
//  * Stages never call each other and are never re-entered. The engine runs them in this order
//    each settle round: duration, core (a timer turn: the simulated bus flushed, then the node's
//    bus deadlines; the MC as the bus shows it to the zones), live view, device info, GNSS (its
//    position to the trackers, the zones and the vehicle state, its fault bit 0x0004 to the
//    node), zones (ZonesStage: zone events and alarms to the recorder, MC writes started
//    through the command service), vehicle state (StateStage: the state and the parked/riding
//    rates to the uplink), recorder (group commit), uplink (poll; the commands, busy notices
//    and retained documents it took are routed to the command service, the campaigns and the
//    zones, and the echoes of what the node sent delivered), status (the retained Status,
//    built when the uplink wants one, the bus state changed or its refresh is due; the route
//    hands it to the uplink, which publishes it). The routes run after their stage; the settle
//    repeats until nothing moves (engine.h).
//  * Results, faults, alarms, rides and locks are published as soon as they are stored (an
//    urgent recorder flush, or result_stored, makes the uplink poll in the same settle); only
//    telemetry waits for its group commit (storage.flush_ms of wall time at the latest; outside
//    replays it is written at any earlier timer turn, which saves a wake-up of its own) and the
//    uplink's telemetry batch.
//  * Deadlines: each stage's next_deadline(), in engine time. The node's come from the bus
//    timeline through the BusClock (runtime/bus_clock.h; none for replays, whose clock only
//    moves with their frames); the listeners' idle tick (1 s) only when the bus is silent.
//    Nothing else wakes the loop: a replay as fast as possible is paced by its transport alone,
//    and an idle bus costs only the node's own schedule.
//  * The simulated bus is read in batches (PacedTransport::set_batch_window, 500 ms) except while
//    a command or the shutdown waits for the bus; it is flushed before the core acts on a
//    deadline and before a command is handled, so batching delays telemetry, never decisions.
//  * Time: the core, trackers and commands run on the bus timeline (BusClock); the network and
//    group commit on the Env's clocks, even when the bus is accelerated.
//  * stop() is idempotent; finish() (after io.run() returned) flushes the recorder, gives the
//    uplink up to 5 s to send what is queued and publishes the retained offline status.
#pragma once

#include <asio/io_context.hpp>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "gateway/campaign/campaign_service.h"
#include "gateway/can/paced_transport.h"
#include "gateway/can/replay_transport.h"
#include "gateway/can/transport.h"
#include "gateway/command/command_service.h"
#include "gateway/config/config.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/node/transport_sender.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/command_stage.h"
#include "gateway/runtime/device_info_reporter.h"
#include "gateway/runtime/engine.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/stages.h"
#include "gateway/runtime/state_stage.h"
#include "gateway/runtime/status_stage.h"
#include "gateway/runtime/status_provider.h"
#include "gateway/runtime/store_outbox.h"
#include "gateway/runtime/zones_stage.h"
#include "gateway/uplink/uplink.h"
#include "storage/store.h"

namespace fleetgw::runtime {

// The CAN transport chosen in the configuration, with typed views of the two that carry their
// own timeline.
struct BusTransport {
  std::unique_ptr<can::Transport> transport;
  can::PacedTransport* sim = nullptr;  // the simulated bike (gateway/sim/sim_bus.h)
  double sim_speed = 1.0;
  can::ReplayTransport* replay = nullptr;
};

struct PipelineOptions {
  std::optional<std::chrono::milliseconds> duration;  // stop after this much wall time
  std::optional<Micros> bus_duration;                 // stop after this much bus time
  bool live_view = false;                             // print LiveState::line() every second
  std::ostream* live_out = nullptr;                   // default std::cout
  std::function<void(GatewayCore&)> on_core;          // before the core starts (tests, demo)
  std::function<void(const char* why)> on_stop;       // the owner stops its own handlers
  // Checked after every settle: stop as soon as it holds (tests and benchmarks wait for an
  // outcome instead of a fixed run length).
  std::function<bool()> stop_when;
  // The environment (clocks); nullptr: the real machine.
  Env* env = nullptr;
};

class CampaignFeed;  // campaign_feed.h

// A stage could not be built from the configuration; what() names the section.
class PipelineError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct PipelineCounters {
  std::uint64_t settles = 0;         // settle() runs
  std::uint64_t timer_wakeups = 0;   // timer expiries handled
  std::uint64_t uplink_polls = 0;    // Uplink::poll calls
  std::uint64_t urgent_flushes = 0;  // recorder flushes because a record was urgent
  std::uint64_t commands = 0;        // payloads handed to the CommandService
};

class Pipeline {
 public:
  // Builds every stage (throws PipelineError for a bad [command] or [mqtt] section) and starts
  // the transport, the core and the uplink; the work happens in io.run(). `store` and `io`
  // must outlive the pipeline.
  Pipeline(asio::io_context& io, const config::Config& config, BusTransport bus,
           storage::Store& store, PipelineOptions options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  void stop(const char* why);
  // After io.run() returned: final flush, last publishes, offline status.
  void finish();
  // finish(): every command the uplink still holds is answered (shutting_down or busy).
  void answer_commands_at_stop();

  // The transport's timeline (see the contract).
  Micros bus_now() const;
  Micros started() const { return start_; }
  bool stopping() const { return stopping_; }

  GatewayCore& core() { return core_; }
  const can::Transport& transport() const { return *bus_.transport; }
  const uplink::Uplink* uplink() const { return uplink_.get(); }
  uplink::Uplink* uplink() { return uplink_.get(); }
  const gnss::GnssFeed* gnss() const { return gnss_.get(); }
  const Engine& engine() const { return engine_; }
  const Recorder& recorder() const { return *recorder_; }
  PipelineCounters counters() const;
  // The geofence section of the status; nullopt when [geofence] is disabled.
  std::optional<GeofenceStatus> geofence_status() const;
  // The campaigns section of the status (issue 29); nullopt without [command.trusted_keys]
  // and [command.root_keys].
  std::optional<nlohmann::json> campaign_status() const;
  // The revocation list version in force (issue 28; 0: none), for the status.
  std::uint64_t revocation_version() const { return commands_->revocation_version(); }
  // Parked (locked and still) or riding; nullopt before the first evaluation.
  std::optional<bool> parked() const { return state_stage_->parked(); }
  // Bus time covered by the frames delivered so far (0 before the first frame).
  double bus_seconds() const;
  // The status socket's document (pipeline_status.cc; runtime/status_provider.h).
  nlohmann::json status_document() const;

 private:
  class CommandFeed;

  void on_frame(const motinova::CanFrame& frame, Micros ts);
  void request_settle() { engine_.request_settle(); }
  // The wiring: the stages in their order and the routes between their outputs and inputs.
  void add_stages();
  bool route_uplink();
  bool route_commands();
  bool route_gnss();
  void after_settle();
  void queue_device_info();
  // Collection campaigns (issue 29; pipeline_campaigns.cc): their topics, the service fed by
  // the core after the recorder, their records queued through the recorder.
  void add_campaign_topics(const config::Config& config, uplink::UplinkConfig& uplink_config);
  void start_campaigns(const config::Config& config);
  // Geofences (issue 14; pipeline_zones.cc): the ZonesStage built from [geofence] and wired to
  // the command service's guards and the lock tracker; its route moves zone events and alarms
  // to the recorder (and the speed authority, the campaigns, the vehicle state) and starts its
  // MC writes through the command service.
  void start_zones(const config::Config& config);
  bool route_zones();
  void start_zone_write(ZonesStage::McWriteRequest write);
  // The vehicle state and parked mode (pipeline_state.cc): the StateStage, its parked listener
  // added to the core, its route handing the state and the parked/riding rates to the uplink.
  void start_state(const config::Config& config);
  bool route_state();
  fleetgw::v1::BusState bus_state() const;
  // The retained status (pipeline_status.cc): built by the status stage, handed to the uplink by
  // its route; want_status() (the uplink's route) asks for one when the uplink wants it or the
  // bus state changed.
  StatusInputs status_inputs() const;
  fleetgw::v1::Status status_message();
  void add_status_stage();
  void want_status();

  asio::io_context& io_;
  PipelineOptions options_;
  BusTransport bus_;
  Env& env_;
  BusClock clock_;
  Engine engine_;
  storage::Store& store_;
  node::TransportSender sender_;
  GatewayCore core_;
  Micros start_{0};
  std::optional<Recorder> recorder_;
  std::unique_ptr<command::CommandService> commands_;
  std::unique_ptr<CommandFeed> command_feed_;
  std::unique_ptr<campaign::CampaignService> campaigns_;  // nullptr without trusted keys
  std::unique_ptr<CampaignFeed> campaign_feed_;
  StoreOutbox outbox_;
  std::unique_ptr<uplink::Uplink> uplink_;
  DeviceInfoReporter device_info_;
  std::unique_ptr<gnss::GnssFeed> gnss_;
  std::string revocations_topic_;  // issue 28: subscribed when root keys are configured

  // The stages, in the order the engine runs them (add_stages()).
  std::unique_ptr<TimerStage> duration_stage_;
  std::unique_ptr<TransportStage> transport_stage_;
  std::unique_ptr<CoreStage> core_stage_;
  std::unique_ptr<TimerStage> live_stage_;
  std::unique_ptr<DeviceInfoStage> device_info_stage_;
  std::unique_ptr<GnssStage> gnss_stage_;
  std::unique_ptr<ZonesStage> zones_stage_;  // nullptr when [geofence] is disabled
  std::unique_ptr<StateStage> state_stage_;  // always (parked mode); the state needs [mqtt]
  std::unique_ptr<CommandStage> command_stage_;
  std::unique_ptr<RecorderStage> recorder_stage_;
  std::unique_ptr<UplinkStage> uplink_stage_;
  std::unique_ptr<StatusStage> status_stage_;  // after the uplink: what it wants is built
  const Backoff* recorder_backoff_ = nullptr;  // the engine's retry state of the recorder
  bool stopping_ = false;
  std::uint64_t commands_handled_ = 0;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);  // guards posted handlers
  const config::Config& config_;  // outlives the pipeline (run_service's); read by the status
  fleetgw::v1::BusState status_bus_state_ = fleetgw::v1::BUS_STATE_UNSPECIFIED;  // last built
};

}  // namespace fleetgw::runtime
