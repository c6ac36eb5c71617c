// Pipeline: the engine of `fleetgw run`. It owns the stages -- GatewayCore (reassembly, decode,
// node), Recorder (domain trackers -> SQLite), CommandService, Uplink (outbox -> MQTT) -- and
// ALL their scheduling, on one asio::io_context thread.
//
// Contract:
//  * Stages never call each other across the pipeline and are never re-entered. They signal:
//    the recorder by urgent()/flush_deadline(), the command service by result_stored /
//    publish_unstored, the uplink by its wake-up (Paho threads) and next_deadline(), the GNSS
//    feed (gpsd) by changed() and next_deadline(): its position goes to the trackers and its
//    fault to the node's own fault word (0x0004) in settle(). The
//    pipeline reacts in settle(), which runs after the handler that raised the signal returned:
//    flush the recorder when urgent, poll the uplink once, hand the commands it took
//    (Uplink::take_commands) to the CommandService, deliver the echoes of what the node sent,
//    and repeat until nothing is left. settle() never runs inside itself.
//  * Results, faults, alarms, rides and locks are published as soon as they are stored (an
//    urgent recorder flush, or result_stored, polls the uplink at once); only telemetry waits
//    for its group commit (storage.flush_ms of wall time at the latest; outside replays it is
//    written at any earlier timer wake-up, which saves a wake-up of its own) and the uplink's
//    telemetry batch.
//  * Deadline scheduling: ONE steady_timer, armed for the earliest real deadline: the node's
//    next deadline (exact; bus timeline converted to the wall clock; not for replays, whose
//    clock only moves with their frames), the listeners' idle tick (1 s, only when the bus is
//    silent), the recorder's flush deadline, the uplink's next deadline, the live view, the
//    run's duration, the retained vehicle state's next check (only after something changed,
//    at most every mqtt.state_interval_ms). Nothing else wakes the loop: a replay as fast as
//    possible is paced by its transport alone, and an idle bus costs only the node's own schedule.
//  * The simulated bus is read in batches (SimTransport::set_batch_window, 500 ms) except while
//    a command or the shutdown waits for the bus; it is flushed before the core acts on a
//    deadline and before a command is handled, so batching delays telemetry, never decisions.
//  * Time: the core, trackers and commands run on the transport's timeline (virtual for the
//    simulator and replays, the system clock otherwise); the network and group commit run on
//    the wall clock, even when the bus is accelerated.
//  * stop() is idempotent; finish() (after io.run() returned) flushes the recorder, gives the
//    uplink up to 5 s to send what is queued and publishes the retained offline status.
#pragma once

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>
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
#include "gateway/can/replay_transport.h"
#include "gateway/can/transport.h"
#include "gateway/command/command_service.h"
#include "gateway/config/config.h"
#include "gateway/geofence/zone_controller.h"
#include "gateway/geofence/zone_lock_watch.h"
#include "gateway/gnss/gnss_feed.h"
#include "gateway/node/transport_sender.h"
#include "gateway/runtime/device_info_reporter.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/parked_mode.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/status_provider.h"
#include "gateway/runtime/store_outbox.h"
#include "gateway/runtime/vehicle_state.h"
#include "gateway/sim/sim_transport.h"
#include "gateway/uplink/uplink.h"
#include "storage/store.h"

namespace fleetgw::runtime {

// The CAN transport chosen in the configuration, with typed views of the two that carry their
// own timeline.
struct BusTransport {
  std::unique_ptr<can::Transport> transport;
  sim::SimTransport* sim = nullptr;
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
};

// A stage could not be built from the configuration; what() names the section.
ParkedConfig make_parked_config(const config::Config& config);
// The zone-bundle topics of [geofence]: bundle_topic (default "<topic_prefix>/zones") and, with
// vehicle_bundles, "<topic_prefix>/<vehicle>/zones" (pipeline_zones.cc).
std::vector<std::string> zone_bundle_topics(const config::Config& config);

class CampaignFeed;  // campaign_feed.h

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
  const Recorder& recorder() const { return *recorder_; }
  const PipelineCounters& counters() const { return counters_; }
  // The geofence section of the status; nullopt when [geofence] is disabled.
  std::optional<GeofenceStatus> geofence_status() const;
  // The campaigns section of the status (issue 29); nullopt without [command.trusted_keys]
  // and [command.root_keys].
  std::optional<nlohmann::json> campaign_status() const;
  // The revocation list version in force (issue 28; 0: none), for the status.
  std::uint64_t revocation_version() const { return commands_->revocation_version(); }
  // Parked (locked and still) or riding; nullopt before the first evaluation.
  std::optional<bool> parked() const { return parked_ ? parked_->parked() : std::nullopt; }
  // Bus time covered by the frames delivered so far (0 before the first frame).
  double bus_seconds() const;

 private:
  class CommandFeed;

  void on_frame(const motinova::CanFrame& frame, Micros ts);
  void request_settle();
  void settle();
  void on_timer();
  void arm_timer();
  std::optional<std::chrono::steady_clock::time_point> core_deadline() const;
  void queue_device_info();
  void apply_gnss();
  // Collection campaigns (issue 29; pipeline_campaigns.cc): their topics, the service fed by
  // the core after the recorder, their records queued through the recorder.
  void add_campaign_topics(const config::Config& config, uplink::UplinkConfig& uplink_config);
  void start_campaigns(const config::Config& config);
  // Geofences (issue 14; pipeline_zones.cc): built from [geofence], fed by apply_gnss(), their
  // MC writes started at each settle through the command service.
  void start_zones(const config::Config& config);
  void apply_zones(Micros wall, const std::optional<gnss::Fix>& position);
  void tick_zones();
  void record_zone_event(const geofence::ZoneEvent& e);  // log, store, queue for the uplink
  // A message of a zone-bundle topic (Uplink::take_zone_bundles), judged, stored, enforced at
  // once; a refusal is logged once per distinct reason and counted for the status.
  void on_zone_bundle(const uplink::ZoneBundleMessage& m);
  // Locks made on the bike (lock events from the bus) noted by the lock observer: reported when
  // they happened in a no-parking zone.
  void judge_bike_locks();
  // Raises / clears the outside_operating_area alarm when the engine's demand changes.
  void update_area_alarm(Micros wall, const std::optional<gnss::Fix>& position);
  std::optional<std::chrono::steady_clock::time_point> zones_deadline() const;
  void update_vehicle_state();
  void attach_parked_feed();
  void apply_parked_rates(bool parked);
  fleetgw::v1::BusState bus_state() const;

  asio::io_context& io_;
  PipelineOptions options_;
  BusTransport bus_;
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
  std::optional<bool> gnss_fault_;  // last value given to the node's fault bit
  // nullptr when [geofence] is disabled.
  std::unique_ptr<geofence::ZoneController> zones_;
  bool zone_write_running_ = false;      // an MC write of the zones is under way
  bool outside_operating_area_ = false;  // the alarm is raised
  Micros area_alarm_since_{0};           // when it was raised
  std::string zone_refusal_;  // the last reason a zone write could not start (logged once)
  std::vector<std::string> zone_topics_;  // the bundle topics subscribed to
  std::string revocations_topic_;         // issue 28: subscribed when root keys are configured
  std::string zone_bundle_file_;
  std::size_t max_bundle_bytes_ = 0;
  std::string bundle_refusal_logged_;  // the last bundle refusal logged (each distinct once)
  std::string bundle_refusal_topic_;   // where the latest refused bundle came from
  geofence::BikeLockWatch bike_locks_;
  struct BikeLock {
    Micros wall{0};
    std::optional<gnss::Fix> fix;  // current when the lock was heard
  };
  std::vector<BikeLock> pending_bike_locks_;  // noted in the recorder's turn, judged in settle()
  StateThrottle state_throttle_;  // when the retained vehicle state is rebuilt (pipeline_state.cc)
  StatePositionFilter state_position_;  // a fix counts as a state change once it moved
  ParkedConfig parked_config_;
  std::unique_ptr<ParkedController> parked_;         // parked/riding (pipeline_state.cc)
  std::chrono::milliseconds parked_batch_delay_{0};  // [parked] telemetry_batch_ms

  asio::steady_timer timer_;
  std::optional<std::chrono::steady_clock::time_point> armed_for_;
  std::optional<std::chrono::steady_clock::time_point> stop_at_;
  std::optional<std::chrono::steady_clock::time_point> next_live_;
  std::atomic<bool> uplink_woken_{false};  // set by Paho threads, consumed by settle()
  bool settle_posted_ = false;
  bool settling_ = false;
  bool publish_due_ = false;  // something was stored that the uplink has not seen
  bool stopping_ = false;
  bool woken_by_timer_ = false;  // this settle() runs in a timer wake-up (flush piggyback)
  Micros first_ts_{-1};
  Micros last_frame_ts_{0};
  PipelineCounters counters_;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);  // guards posted handlers
};

}  // namespace fleetgw::runtime
