#include "gateway/runtime/pipeline.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <asio/post.hpp>
#include <cmath>
#include <iostream>

#include "gateway/node/messages.h"
#include "gateway/runtime/campaign_feed.h"
#include "gateway/runtime/clock_units.h"
#include "gateway/runtime/service.h"

namespace fleetgw::runtime {
namespace {

using Clock = std::chrono::steady_clock;

// The simulated bus delivers its traffic in batches at most this often (real time) while no
// command waits for the bus: frames keep their own timestamps and are flushed before the core
// acts on any deadline, so only the wall-clock latency of telemetry grows (it waits for its
// group commit anyway), not the node's timing. Each wake-up of the event loop costs far more
// than the frames it delivers; this is what makes real time cost about what a replay costs.
constexpr auto kSimBatchWindow = std::chrono::milliseconds(500);

BusClock make_bus_clock(const Env& env, const BusTransport& bus) {
  if (bus.sim) {
    return BusClock::simulated(
        env, [sim = bus.sim] { return sim->virtual_now(); }, bus.sim_speed);
  }
  if (bus.replay) return BusClock::replay(env);
  return BusClock::system(env);
}

}  // namespace

// The bus side of the command service: every decoded bus message (motion interlock, MC and
// diagnostic answers) and the core's tick (timeouts, retries). It runs inside the transport's
// read handler and only notes in memory; the command stage writes (command_stage.h).
class Pipeline::CommandFeed final : public MessageListener {
 public:
  explicit CommandFeed(command::CommandService& service) : service_(service) {}
  void on_message(const motinova::DecodedMessage& m, Micros t) override {
    service_.on_message(m, t);
  }
  void tick(Micros t) override { service_.tick(t); }

 private:
  command::CommandService& service_;
};

Pipeline::Pipeline(asio::io_context& io, const config::Config& config, BusTransport bus,
                   storage::Store& store, PipelineOptions options)
    : io_(io),
      options_(std::move(options)),
      bus_(std::move(bus)),
      env_(options_.env ? *options_.env : Env::system()),
      clock_(make_bus_clock(env_, bus_)),
      engine_(io, env_),
      store_(store),
      sender_(*bus_.transport, config.protocol.crc_order),
      core_(
          config, sender_,
          node::NodeHooks{
              .on_peer_shutdown =
                  [](motinova::Node initiator, Micros) {
                    spdlog::info("{} broadcast SHUTDOWN: state saved, answering READY",
                                 motinova::node_name(initiator));
                  },
              .acc_off =
                  [](const node::ShutdownOutcome&) { spdlog::info("shutdown complete: ACC off"); },
          }),
      outbox_(store, env_),
      device_info_(core_.node().config().identity),
      config_(config) {
  if (auto* work = bus_.transport->timed_work()) work->set_wake([this] { request_settle(); });
  bus_.transport->start([this](const motinova::CanFrame& frame, Micros ts) { on_frame(frame, ts); },
                        [this](const can::BusHealth& h) {
                          spdlog::info("bus {}: {}{}{}", bus_.transport->name(),
                                       can::controller_state_name(h.state),
                                       h.detail.empty() ? "" : ": ", h.detail);
                        });
  if (bus_.sim) bus_.sim->set_batch_window(kSimBatchWindow);
  start_ = bus_.replay ? Micros(0) : bus_now();
  recorder_.emplace(config, store_, start_, env_);
  recorder_->set_flush_on_tick(false);  // settle() flushes: one transaction per burst of frames

  // Remote lock commands: verified, journaled in the store, executed through the node.
  command::CommandContext context{
      .node = core_.node(),
      .store = store_,
      .trackers = &recorder_->trackers(),
      .clock_synchronised = command::default_clock_synchronised,
      .wall_clock = [this] { return env_.wall_now(); },
  };
  try {
    commands_ = std::make_unique<command::CommandService>(
        command::make_command_service_config(config), std::move(context));
  } catch (const std::exception& e) {
    throw PipelineError(std::string("invalid [command] configuration: ") + e.what());
  }
  if (const auto n = commands_->recover(start_)) {
    spdlog::warn("{} command(s) interrupted by the previous stop finished as timeout", n);
  }
  command_feed_ = std::make_unique<CommandFeed>(*commands_);
  core_.add_listener(*command_feed_);

  if (config.mqtt.enabled) {
    try {
      uplink::UplinkConfig uplink_config = make_uplink_config(config);
      uplink_config.store_id = store_.store_id();
      if (config.geofence.enabled) {
        uplink_config.zone_topics = zone_bundle_topics(config);
        uplink_config.max_zone_bundle_bytes =
            static_cast<std::size_t>(config.geofence.max_bundle_bytes);
      }
      add_campaign_topics(config, uplink_config);
      // Issue 28: the root's revocation list, retained; judged by the command service.
      if (!config.command.root_keys.empty()) {
        revocations_topic_ =
            uplink::Topics(config.mqtt.topic_prefix, config.vehicle.id).revocations;
        uplink_config.zone_topics.push_back(revocations_topic_);
      }
      // Every retained document topic (zones fleet-wide and per vehicle, campaigns, the
      // revocation list) delivers its message at each connect, in one burst: the queue holds one
      // per topic and one live update more, so the burst never drops a document. The memory
      // bound stays (topics + 1) x the largest accepted payload.
      uplink_config.max_queued_zone_bundles =
          std::max(uplink_config.max_queued_zone_bundles, uplink_config.zone_topics.size() + 1);
      uplink_ = std::make_unique<uplink::Uplink>(std::move(uplink_config), outbox_, env_);
    } catch (const std::exception& e) {
      throw PipelineError(std::string("invalid [mqtt] configuration: ") + e.what());
    }
    // Junk cannot crowd out signed commands: Paho's thread checks each signature before it is
    // queued (docs/commands.md "Bursts and floods").
    uplink_->set_command_authenticator(
        [auth = commands_->authenticator()](std::string_view payload) {
          auto a = auth({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()});
          return uplink::CommandTriage{a.authenticated, std::move(a.command_id),
                                       std::move(a.command_sha256)};
        });
    // Paho's threads only raise a flag and, once, post a settle to the loop.
    uplink_stage_ = std::make_unique<UplinkStage>(*uplink_, engine_, &outbox_);
    uplink_->set_wakeup([stage = uplink_stage_.get()] { stage->signal(); });
  }
  core_.add_listener(*recorder_);
  start_campaigns(config);  // a listener after the recorder
  // Parked mode's listener after the recorder: it reads what the trackers just concluded.
  start_state(config);
  // Node identities go to the backend at start (our own) and whenever one is heard or changes.
  core_.node().registry().add_observer(device_info_);
  queue_device_info();
  if (options_.on_core) options_.on_core(core_);
  core_.start(start_);

  if (bus_.replay) {
    bus_.replay->on_end([this](const can::ReplaySummary& s) {
      spdlog::info("replay finished: {} lines, {} frames, {} malformed lines", s.lines, s.frames,
                   s.malformed_lines);
      core_.tick(clock_.last_frame() + GatewayCore::kTickInterval);
      stop("end of replay");
    });
  }
  if (uplink_) {
    uplink_->start(env_.wall_now());
    uplink_stage_->stored();  // whatever the outbox kept from the previous run
  }
  if (config.gnss.enabled) {
    const auto colon = config.gnss.gpsd.rfind(':');
    gnss::GnssFeedOptions o;
    o.host = config.gnss.gpsd.substr(0, colon);
    o.port = colon == std::string::npos ? "2947" : config.gnss.gpsd.substr(colon + 1);
    o.state.max_age = std::chrono::milliseconds(config.gnss.max_age_ms);
    o.reconnect_max = std::chrono::milliseconds(config.gnss.reconnect_max_ms);
    gnss_ = std::make_unique<gnss::GnssFeed>(io_, std::move(o), env_, [this] { request_settle(); });
  }
  start_zones(config);
  add_stages();
  request_settle();
}

Pipeline::~Pipeline() {
  core_.node().registry().remove_observer(device_info_);
  alive_.reset();
  // First: Paho's threads may call the wake-up (which touches this object) until the client
  // is gone.
  uplink_.reset();
}

Micros Pipeline::bus_now() const {
  return clock_.now();
}

double Pipeline::bus_seconds() const {
  return clock_.seconds_covered();
}

PipelineCounters Pipeline::counters() const {
  PipelineCounters c;
  c.settles = engine_.counters().settles;
  c.timer_wakeups = engine_.counters().timer_wakeups;
  c.uplink_polls = uplink_stage_ ? uplink_stage_->polls() : 0;
  c.urgent_flushes = recorder_stage_ ? recorder_stage_->urgent_flushes() : 0;
  c.commands = commands_handled_ + (command_stage_ ? command_stage_->handled() : 0);
  return c;
}

void Pipeline::add_stages() {
  // The run's own deadlines come first: a duration reached stops before anything else runs.
  if (options_.duration) {
    duration_stage_ = std::make_unique<TimerStage>(
        "duration", env_.steady_now() + *options_.duration, Clock::duration::zero());
    engine_.add(*duration_stage_, [this] {
      if (duration_stage_->take_due()) stop("duration reached");
      return false;
    });
  }
  // The transport's re-opens and transmit retries: the engine's timer and back-off time them.
  if (auto* work = bus_.transport->timed_work()) {
    transport_stage_ = std::make_unique<TransportStage>(*work);
    engine_.add(*transport_stage_, {}, transport_stage_->backoff());
  }
  core_stage_ = std::make_unique<CoreStage>(core_, clock_, bus_.sim, engine_);
  engine_.add(*core_stage_, [this] {
    // A tick may have raised or cleared an alarm.
    if (core_stage_->take_timer_turn()) state_stage_->touch();
    // The zones' enforcer sees the MC as the bus shows it now, and whether a command runs.
    if (zones_stage_) {
      geofence::McView mc;
      mc.assist_level = core_.live().assist;
      // The limit in force as the MC last reported it: the enforcer writes the authority's
      // limit only when it differs.
      if (const auto limit = core_.live().speed_limit_kmh)
        mc.speed_limit_kmh = static_cast<int>(std::lround(*limit));
      mc.busy = commands_->busy();
      zones_stage_->set_mc(mc);
    }
    return false;
  });
  if (options_.live_view) {
    live_stage_ = std::make_unique<TimerStage>(
        "live_view", env_.steady_now() + std::chrono::seconds(1), std::chrono::seconds(1));
    engine_.add(*live_stage_, [this] {
      if (live_stage_->take_due()) {
        std::ostream& out = options_.live_out ? *options_.live_out : std::cout;
        out << core_.live().line() << std::endl;
      }
      return false;
    });
  }
  device_info_stage_ = std::make_unique<DeviceInfoStage>(device_info_, core_.node().registry());
  engine_.add(*device_info_stage_, [this] {
    if (!device_info_stage_->record) return false;
    recorder_->queue_message(std::move(*device_info_stage_->record));
    device_info_stage_->record.reset();
    return false;  // the recorder runs later in this round
  });
  if (gnss_) {
    gnss_stage_ = std::make_unique<GnssStage>(*gnss_, engine_);
    // The engine times gpsd's reconnects with its one back-off (GnssStage reports failures).
    engine_.add(*gnss_stage_, [this] { return route_gnss(); },
                Backoff::Options{.initial = gnss_->options().reconnect_min,
                                 .max = gnss_->options().reconnect_max});
  }
  if (zones_stage_) engine_.add(*zones_stage_, [this] { return route_zones(); });
  engine_.add(*state_stage_, [this] { return route_state(); });
  // Before the recorder and the uplink: a result written here is published in the same round.
  command_stage_ = std::make_unique<CommandStage>(*commands_, clock_, bus_.sim, engine_);
  engine_.add(*command_stage_, [this] { return route_commands(); });
  recorder_stage_ = std::make_unique<RecorderStage>(*recorder_, clock_, engine_);
  engine_.add(
      *recorder_stage_,
      [this] {
        if (recorder_stage_->take_stored() && uplink_stage_) uplink_stage_->stored();
        return false;  // the uplink runs next in this round
      },
      // The store's retry interval (one attempt per second of wall time while it fails).
      Backoff::Options{.initial = Recorder::kRetryInterval, .max = Recorder::kRetryInterval});
  recorder_backoff_ = engine_.backoff(*recorder_stage_);
  if (uplink_stage_) {
    engine_.add(*uplink_stage_, [this] { return route_uplink(); });
    add_status_stage();
  }
  engine_.set_after_settle([this] { after_settle(); });
}

void Pipeline::on_frame(const motinova::CanFrame& frame, Micros ts) {
  if (stopping_) return;
  clock_.on_frame(ts);
  core_.on_can_frame(frame, ts);
  state_stage_->touch();  // the live values may have changed: a check at the next allowed time
  // Model blocks heard in one burst of frames become one DeviceInfo (queued in the settle).
  if (device_info_.due()) request_settle();
  // Measured on the frames actually delivered: a paced simulator's clock can run ahead of a
  // slow machine, the traffic cannot.
  if (options_.bus_duration && ts - clock_.first_frame() >= *options_.bus_duration) {
    stop("bus duration reached");
    return;
  }
  // A result concluded on the bus (a lock confirmed) is written by the command stage, not here.
  if (command_stage_ && command_stage_->due()) request_settle();
  if (recorder_->urgent()) {
    // A failing store is retried at the engine's back-off, not at every frame.
    if (!recorder_backoff_->waiting(env_.steady_now())) request_settle();
  } else if (!engine_.armed() && recorder_->flush_deadline()) {
    engine_.rearm();  // first pending telemetry while nothing else is scheduled (replays)
  }
}

bool Pipeline::route_gnss() {
  bool moved = false;
  if (gnss_stage_->update) {
    auto u = *std::exchange(gnss_stage_->update, std::nullopt);
    state_stage_->on_position(u.position);
    recorder_->trackers().on_position(u.position);
    if (zones_stage_) zones_stage_->on_position(u.wall, std::move(u.position));
    moved = true;
  }
  if (gnss_stage_->fault) {
    core_.node().set_own_fault(node::iot_fault::kGps, *gnss_stage_->fault, bus_now());
    gnss_stage_->fault.reset();
    moved = true;
  }
  return moved;
}

bool Pipeline::route_uplink() {
  UplinkStage& up = *uplink_stage_;
  want_status();
  bool moved = false;
  // Commands, busy notices and the revocation list: the command stage's inputs (next round).
  CommandStage& cs = *command_stage_;
  auto append = [&moved](auto& to, auto& from) {
    for (auto& x : std::exchange(from, {})) to.push_back(std::move(x));
    moved = true;
  };
  if (!up.commands.empty()) append(cs.payloads, up.commands);
  if (!up.busy.empty()) append(cs.busy, up.busy);
  for (auto& [tag, ok] : std::exchange(up.direct_handed, {})) {
    cs.handed.push_back({std::move(tag), ok});
    moved = true;
  }
  // Zone bundles: judged here, on the loop, like commands (Paho only queued them).
  for (auto& bundle : std::exchange(up.bundles, {})) {
    if (!revocations_topic_.empty() && bundle.topic == revocations_topic_) {
      cs.revocations.push_back(std::move(bundle.payload));
    } else if (campaigns_ && campaigns_->handles(bundle.topic)) {
      campaigns_->on_payload(bundle.topic, bundle.payload, bundle.oversized_bytes, bus_now(),
                             bus_now());
    } else if (zones_stage_) {
      zones_stage_->on_bundle(std::move(bundle));
    }
    moved = true;
  }
  // Records the commands produced are stored in the next round (a failing store: at its retry).
  if (up.publish_due() || (recorder_->urgent() && !recorder_backoff_->waiting(env_.steady_now()))) {
    moved = true;
  }
  return moved;
}

bool Pipeline::route_commands() {
  CommandStage& cs = *command_stage_;
  // The LOCK/UNLOCK a command sent reach the trackers after the command's own work.
  if (core_.echoes_pending()) core_.deliver_echoes();
  bool moved = false;
  // Stored results: the uplink (later in this round) publishes them.
  if (std::exchange(cs.stored, 0) > 0 && uplink_stage_) uplink_stage_->stored();
  // Results the store refused: published directly by the uplink stage, or not at all.
  for (auto& u : std::exchange(cs.unstored, {})) {
    if (uplink_stage_) {
      uplink_stage_->direct.push_back(
          {uplink::kind::kCommandResult, std::move(u.serialized), std::move(u.command_id)});
    } else {
      cs.handed.push_back({std::move(u.command_id), false});
      moved = true;
    }
  }
  return moved;
}

void Pipeline::after_settle() {
  // After the publishes, so a checkpoint's fsync never sits between a result and the broker.
  recorder_->checkpoint_if_due();
  if (options_.stop_when && options_.stop_when()) {
    stop("stop condition met");
    return;
  }
  // A command (or shutdown) waiting for the bus gets every frame at once.
  if (bus_.sim) bus_.sim->set_low_latency(commands_->busy() || core_.latency_critical());
}

void Pipeline::stop(const char* why) {
  if (stopping_) return;
  stopping_ = true;
  spdlog::info("stopping: {}", why);
  engine_.stop();
  bus_.transport->stop();
  if (gnss_) gnss_->stop();
  if (options_.on_stop) options_.on_stop(why);
}

void Pipeline::queue_device_info() {
  if (auto payload = device_info_.take(core_.node().registry())) {
    recorder_->queue_message(storage::UplinkMessage{
        storage::OutboxKind::kInfo, static_cast<int>(storage::OutboxPriority::kPack),
        storage::Bytes(payload->begin(), payload->end())});
  }
}

fleetgw::v1::BusState Pipeline::bus_state() const {
  return runtime::bus_state(*bus_.transport, clock_,
                            core_.node().registry().config().offline_timeout);
}

void Pipeline::answer_commands_at_stop() {
  // Outside the engine (it stopped): what waits in the stages' queues, then what the uplink
  // holds -- every command answered shutting_down or busy.
  CommandStage& cs = *command_stage_;
  std::vector<std::string> payloads = std::exchange(cs.payloads, {});
  std::vector<uplink::BusyCommand> busy = std::exchange(cs.busy, {});
  std::vector<command::UnstoredResult> unstored = std::exchange(cs.unstored, {});
  if (uplink_stage_) {
    for (auto& p : std::exchange(uplink_stage_->commands, {})) payloads.push_back(std::move(p));
    for (auto& b : std::exchange(uplink_stage_->busy, {})) busy.push_back(std::move(b));
    for (auto& d : std::exchange(uplink_stage_->direct, {})) {
      unstored.push_back({std::move(d.tag), std::move(d.payload)});
    }
    for (auto& [tag, ok] : std::exchange(uplink_stage_->direct_handed, {})) {
      cs.handed.push_back({std::move(tag), ok});
    }
  }
  if (uplink_) {
    for (auto& p : uplink_->take_commands()) payloads.push_back(std::move(p));
    for (auto& b : uplink_->take_busy_commands()) busy.push_back(std::move(b));
  }
  for (const auto& h : std::exchange(cs.handed, {})) {
    commands_->unstored_handed(h.command_id, h.handed);
  }
  for (const auto& payload : payloads) {
    ++commands_handled_;
    commands_->answer_stopping(
        {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, bus_now());
  }
  for (const auto& b : busy) {
    ++commands_handled_;
    commands_->answer_busy(b.command_id, b.command_sha256, bus_now());
  }
  // Results concluded on the bus since the last settle written (the drain publishes the
  // outbox); the unstored ones published directly.
  commands_->run(bus_now());
  commands_->take_stored();
  for (auto& u : commands_->take_unstored()) unstored.push_back(std::move(u));
  for (auto& u : unstored) {
    const bool ok = uplink_ && uplink_->publish_direct(uplink::kind::kCommandResult,
                                                       std::move(u.serialized), env_.wall_now());
    commands_->unstored_handed(u.command_id, ok);
  }
}

void Pipeline::finish() {
  // Everything the trackers hold goes to the store, and a clean stop then drains the outbox
  // (the last telemetry batch included: it no longer waits for its batch delay) within the
  // grace, before the retained offline status.
  if (device_info_.due()) queue_device_info();
  recorder_->flush(bus_now());
  if (!uplink_) {
    answer_commands_at_stop();  // results concluded on the bus still written
    return;
  }
  // The state the clean stop leaves retained (online = false) is the current one, not the last
  // one the throttle let through.
  if (state_stage_->check_now()) route_state();
  // Commands still queued, or arriving while the outbox drains, are answered shutting_down
  // (never run: the bus is stopped), so none is left without a result. What the drain does not
  // publish stays in the outbox for the next start.
  answer_commands_at_stop();
  uplink_->drain_for_stop();
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  while (Clock::now() < deadline && uplink_->state() == uplink::UplinkState::kConnected) {
    answer_commands_at_stop();
    if (outbox_.stats().depth == 0) break;
    uplink_->poll(env_.wall_now());
    uplink_->wait_for_events(std::chrono::milliseconds(50));
  }
  uplink_->set_status(status_message());  // the offline status shows the stop's figures
  uplink_->stop(env_.wall_now());
  answer_commands_at_stop();
  const auto s = uplink_->stats();
  spdlog::info("uplink: {} records acked in {} messages, {} reconnects, {} still queued",
               s.acked_records, s.acked_messages, s.reconnects, outbox_.stats().depth);
}

}  // namespace fleetgw::runtime
