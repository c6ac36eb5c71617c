#include "gateway/runtime/pipeline.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <asio/post.hpp>
#include <iostream>

#include "gateway/node/messages.h"
#include "gateway/runtime/campaign_feed.h"
#include "gateway/runtime/clock_units.h"
#include "gateway/runtime/service.h"

namespace fleetgw::runtime {
namespace {

using Clock = std::chrono::steady_clock;

// settle() repeats while stages keep producing work; a bound keeps one loop turn short even if
// a stage misbehaves (the rest is picked up by the next settle, which is posted).
constexpr int kMaxSettleRounds = 16;
// The simulator's clock is converted to the wall clock; never wait less than this for it.
constexpr auto kMinSimWait = std::chrono::microseconds(200);
// The simulated bus delivers its traffic in batches at most this often (real time) while no
// command waits for the bus: frames keep their own timestamps and are flushed before the core
// acts on any deadline, so only the wall-clock latency of telemetry grows (it waits for its
// group commit anyway), not the node's timing. Each wake-up of the event loop costs far more
// than the frames it delivers; this is what makes real time cost about what a replay costs.
constexpr auto kSimBatchWindow = std::chrono::milliseconds(500);

}  // namespace

// The command service sees every decoded bus message (motion interlock, lock confirmations)
// and the core's tick (timeouts, retries).
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
      outbox_(store),
      device_info_(core_.node().config().identity),
      state_throttle_(
          std::chrono::milliseconds(config.mqtt.enabled ? config.mqtt.state_interval_ms : 0)),
      state_position_(config.mqtt.state_min_move_m),
      parked_config_(make_parked_config(config)),
      timer_(io) {
  bus_.transport->start([this](const motinova::CanFrame& frame, Micros ts) { on_frame(frame, ts); },
                        [this](const can::BusHealth& h) {
                          spdlog::info("bus {}: {}{}{}", bus_.transport->name(),
                                       can::controller_state_name(h.state),
                                       h.detail.empty() ? "" : ": ", h.detail);
                        });
  if (bus_.sim) bus_.sim->set_batch_window(kSimBatchWindow);
  start_ = bus_.replay ? Micros(0) : bus_now();
  recorder_.emplace(config, store_, start_);
  recorder_->set_flush_on_tick(false);  // settle() flushes: one transaction per burst of frames

  // Remote lock commands: verified, journaled in the store, executed through the node.
  command::CommandContext context{
      .node = core_.node(),
      .store = store_,
      .trackers = &recorder_->trackers(),
      .clock_synchronised = command::default_clock_synchronised,
      .wall_clock = system_now,
      // A stored result is published in the next settle, not at a timer.
      .result_stored =
          [this] {
            if (!uplink_) return;
            publish_due_ = true;
            request_settle();
          },
      .publish_unstored =
          [this](std::string serialized) {
            return uplink_ && uplink_->publish_direct(uplink::kind::kCommandResult,
                                                      std::move(serialized), system_now());
          },
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
        zone_topics_ = zone_bundle_topics(config);
        max_bundle_bytes_ = static_cast<std::size_t>(config.geofence.max_bundle_bytes);
        uplink_config.zone_topics = zone_topics_;
        uplink_config.max_zone_bundle_bytes = max_bundle_bytes_;
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
      uplink_ = std::make_unique<uplink::Uplink>(std::move(uplink_config), outbox_);
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
    uplink_->set_wakeup([this, token = std::weak_ptr<int>(alive_)] {
      if (uplink_woken_.exchange(true)) return;
      asio::post(io_, [this, token] {
        if (!token.expired()) settle();
      });
    });
  }
  core_.add_listener(*recorder_);
  start_campaigns(config);  // a listener after the recorder
  parked_batch_delay_ = std::chrono::milliseconds(config.parked.telemetry_batch_ms);
  attach_parked_feed();  // after the recorder: it reads what the trackers just concluded
  // Node identities go to the backend at start (our own) and whenever one is heard or changes.
  core_.node().registry().add_observer(device_info_);
  queue_device_info();
  if (options_.on_core) options_.on_core(core_);
  core_.start(start_);

  if (options_.duration) stop_at_ = Clock::now() + *options_.duration;
  if (options_.live_view) next_live_ = Clock::now() + std::chrono::seconds(1);
  if (bus_.replay) {
    bus_.replay->on_end([this](const can::ReplaySummary& s) {
      spdlog::info("replay finished: {} lines, {} frames, {} malformed lines", s.lines, s.frames,
                   s.malformed_lines);
      core_.tick(last_frame_ts_ + GatewayCore::kTickInterval);
      stop("end of replay");
    });
  }
  if (uplink_) {
    uplink_->start(system_now());
    publish_due_ = true;  // whatever the outbox kept from the previous run
  }
  if (config.gnss.enabled) {
    const auto colon = config.gnss.gpsd.rfind(':');
    gnss::GnssFeedOptions o;
    o.host = config.gnss.gpsd.substr(0, colon);
    o.port = colon == std::string::npos ? "2947" : config.gnss.gpsd.substr(colon + 1);
    o.state.max_age = std::chrono::milliseconds(config.gnss.max_age_ms);
    o.reconnect_max = std::chrono::milliseconds(config.gnss.reconnect_max_ms);
    gnss_ = std::make_unique<gnss::GnssFeed>(io_, std::move(o), system_now,
                                             [this] { request_settle(); });
    gnss_->start();
  }
  start_zones(config);
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
  // The simulator's frames carry its virtual time; once they flow they are the clock, so a
  // machine too slow for the acceleration sees a consistent (if slower) timeline.
  if (bus_.sim) return last_frame_ts_.count() > 0 ? last_frame_ts_ : bus_.sim->virtual_now();
  if (bus_.replay) return last_frame_ts_;
  return system_now();
}

double Pipeline::bus_seconds() const {
  return first_ts_.count() < 0 ? 0.0
                               : static_cast<double>((last_frame_ts_ - first_ts_).count()) / 1e6;
}

void Pipeline::on_frame(const motinova::CanFrame& frame, Micros ts) {
  if (stopping_) return;
  if (first_ts_.count() < 0) first_ts_ = ts;
  last_frame_ts_ = ts;
  core_.on_can_frame(frame, ts);
  state_throttle_.touch();  // the live values may have changed: a check at the next allowed time
  // Model blocks heard in one burst of frames become one DeviceInfo (queued in settle()).
  if (device_info_.due()) request_settle();
  // Measured on the frames actually delivered: a paced simulator's clock can run ahead of a
  // slow machine, the traffic cannot.
  if (options_.bus_duration && ts - first_ts_ >= *options_.bus_duration) {
    stop("bus duration reached");
    return;
  }
  if (recorder_->urgent()) {
    request_settle();
  } else if (!armed_for_ && recorder_->flush_deadline()) {
    arm_timer();  // first pending telemetry while nothing else is scheduled (replays)
  }
}

void Pipeline::request_settle() {
  if (settling_) return;  // the running settle() loops again
  if (settle_posted_ || stopping_) return;
  settle_posted_ = true;
  asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
    if (token.expired()) return;
    settle_posted_ = false;
    settle();
  });
}

void Pipeline::settle() {
  if (settling_ || stopping_) return;
  settling_ = true;
  ++counters_.settles;
  for (int round = 0; round < kMaxSettleRounds; ++round) {
    bool more = false;
    if (device_info_.due()) queue_device_info();
    if (gnss_ && gnss_->changed()) apply_gnss();
    if (zones_ && !pending_bike_locks_.empty()) judge_bike_locks();
    if (zones_) tick_zones();
    if (uplink_ && state_throttle_.due(Clock::now())) update_vehicle_state();
    const auto due = recorder_->flush_deadline();
    const bool urgent = recorder_->urgent();
    // The deadline is "at the latest": pending telemetry rides along with a wake-up that
    // happens anyway (the node's schedule) instead of costing one of its own. Not in a replay,
    // whose group commits should stay large.
    const bool piggyback = woken_by_timer_ && !bus_.replay;
    woken_by_timer_ = false;
    if (urgent || (due && (piggyback || Clock::now() >= *due))) {
      if (urgent) ++counters_.urgent_flushes;
      const FlushOutcome out = recorder_->flush(bus_now());
      if (uplink_ && out.records > 0 && !out.failed) publish_due_ = true;
    }
    if (uplink_) {
      uplink_->set_bus_state(bus_state());
      const auto poll_at = uplink_->next_deadline();
      const bool woken = uplink_woken_.exchange(false);
      if (publish_due_ || woken || (poll_at && Clock::now() >= *poll_at)) {
        publish_due_ = false;
        ++counters_.uplink_polls;
        uplink_->poll(system_now());
        // Commands are handled after poll() returned: poll is never re-entered.
        auto payloads = uplink_->take_commands();
        // A command acts on the bus as it is now, not as of the last batch.
        if (!payloads.empty() && bus_.sim) bus_.sim->flush();
        for (auto& payload : payloads) {
          ++counters_.commands;
          const auto d = commands_->on_payload(payload, bus_now());
          spdlog::info("command received: {}", command::disposition_name(d));
          core_.deliver_echoes();  // the LOCK/UNLOCK it sent, after the command's own work
          more = true;
        }
        // What the full queue could not take: each answered `busy`, none silently lost.
        for (const auto& busy : uplink_->take_busy_commands()) {
          ++counters_.commands;
          commands_->answer_busy(busy.command_id, busy.command_sha256, bus_now());
          more = true;
        }
        // Zone bundles: judged here, on the loop, like commands (Paho only queued them).
        for (const auto& bundle : uplink_->take_zone_bundles()) {
          if (!revocations_topic_.empty() && bundle.topic == revocations_topic_) {
            commands_->on_revocations({reinterpret_cast<const std::uint8_t*>(bundle.payload.data()),
                                       bundle.payload.size()},
                                      system_now());
          } else if (campaigns_ && campaigns_->handles(bundle.topic)) {
            campaigns_->on_payload(bundle.topic, bundle.payload, bundle.oversized_bytes, bus_now(),
                                   bus_now());
          } else if (zones_) {
            on_zone_bundle(bundle);
          }
          more = true;
        }
      }
    }
    if (publish_due_ || recorder_->urgent()) more = true;
    if (!more) break;
  }
  settling_ = false;
  // After the publishes, so a checkpoint's fsync never sits between a result and the broker.
  recorder_->checkpoint_if_due();
  // The bound was reached (or a flush failed and keeps its records: retried at the deadline).
  if (options_.stop_when && options_.stop_when()) {
    stop("stop condition met");
    return;
  }
  if (publish_due_) request_settle();
  // A command (or shutdown) waiting for the bus gets every frame at once.
  if (bus_.sim) bus_.sim->set_low_latency(commands_->busy() || core_.latency_critical());
  arm_timer();
}

std::optional<Clock::time_point> Pipeline::core_deadline() const {
  // A replay's clock only moves with its frames, and on_can_frame() ticks the core by itself.
  if (bus_.replay) return std::nullopt;
  // The node's own deadlines are exact; the listeners (trackers, commands) need the timer only
  // on a silent bus, at their idle cadence: flowing frames tick them (on_can_frame).
  const Micros next = std::min(core_.node_deadline(), core_.idle_deadline());
  if (bus_.sim) {
    // Bus time -> wall time through the acceleration, on the simulator's own clock.
    const Micros now = bus_.sim->virtual_now();
    const auto wait =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::micro>(
            static_cast<double>((next - now).count()) / bus_.sim_speed));
    return Clock::now() + std::max<Clock::duration>(wait, kMinSimWait);
  }
  return Clock::now() + std::max<Clock::duration>(next - system_now(), Clock::duration::zero());
}

void Pipeline::arm_timer() {
  if (stopping_) return;
  std::optional<Clock::time_point> at;
  auto consider = [&](std::optional<Clock::time_point> t) {
    if (t && (!at || *t < *at)) at = t;
  };
  consider(core_deadline());
  consider(recorder_->flush_deadline());
  if (uplink_) consider(uplink_->next_deadline());
  if (gnss_) consider(gnss_->next_deadline());
  if (zones_) consider(zones_deadline());
  consider(state_throttle_.deadline());
  consider(next_live_);
  consider(stop_at_);
  if (!at) {
    if (armed_for_) timer_.cancel();
    armed_for_.reset();
    return;
  }
  if (armed_for_ && *armed_for_ == *at) return;
  armed_for_ = at;
  timer_.expires_at(*at);
  timer_.async_wait([this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
    // A cancelled wait (re-armed or stopped) does nothing: the new wait is already pending.
    if (ec || token.expired() || stopping_) return;
    armed_for_.reset();
    on_timer();
  });
}

void Pipeline::on_timer() {
  ++counters_.timer_wakeups;
  const auto wall = Clock::now();
  if (stop_at_ && wall >= *stop_at_) {
    stop("duration reached");
    return;
  }
  if (!bus_.replay) {
    Micros t = bus_now();
    if (bus_.sim) {
      // The core acts on its deadline with every frame due by now delivered (batching).
      bus_.sim->flush();
      if (stopping_) return;
      t = std::max(bus_now(), bus_.sim->virtual_now());
    }
    if (t >= core_.next_event()) core_.tick(t);
  }
  if (gnss_) gnss_->on_timer();
  state_throttle_.touch();  // a tick may have raised or cleared an alarm
  if (next_live_ && wall >= *next_live_) {
    std::ostream& out = options_.live_out ? *options_.live_out : std::cout;
    out << core_.live().line() << std::endl;
    next_live_ = wall + std::chrono::seconds(1);
  }
  woken_by_timer_ = true;
  settle();  // due flushes and polls; re-arms the timer
}

void Pipeline::stop(const char* why) {
  if (stopping_) return;
  stopping_ = true;
  spdlog::info("stopping: {}", why);
  bus_.transport->stop();
  if (gnss_) gnss_->stop();
  timer_.cancel();
  armed_for_.reset();
  if (options_.on_stop) options_.on_stop(why);
}

void Pipeline::queue_device_info() {
  if (auto payload = device_info_.take(core_.node().registry())) {
    recorder_->queue_message(storage::UplinkMessage{
        storage::OutboxKind::kInfo, static_cast<int>(storage::OutboxPriority::kPack),
        storage::Bytes(payload->begin(), payload->end())});
  }
}

void Pipeline::apply_gnss() {
  gnss_->take_changed();
  state_throttle_.touch();
  const auto wall = gnss_->wall_now();
  const auto position = gnss_->state().current(wall);
  recorder_->trackers().on_position(position);
  if (zones_) apply_zones(wall, position);
  const bool fault = !position;
  if (gnss_fault_ != fault) {
    if (fault) {
      spdlog::warn("gnss: position unknown ({}): IoT fault bit 0x0004 set",
                   gnss_->state().reason(wall));
    } else if (gnss_fault_) {
      spdlog::info("gnss: fix acquired: IoT fault bit 0x0004 cleared");
    }
    gnss_fault_ = fault;
    core_.node().set_own_fault(node::iot_fault::kGps, fault, bus_now());
  }
}

fleetgw::v1::BusState Pipeline::bus_state() const {
  switch (bus_.transport->health().state) {
    case can::ControllerState::kBusOff:
      return fleetgw::v1::BUS_STATE_BUS_OFF;
    case can::ControllerState::kErrorPassive:
      return fleetgw::v1::BUS_STATE_ERROR_PASSIVE;
    case can::ControllerState::kDown:
      return fleetgw::v1::BUS_STATE_SILENT;
    case can::ControllerState::kUp:
    case can::ControllerState::kErrorWarning:
      break;
  }
  // Frames flowing: heard within the time after which a node counts as offline.
  if (first_ts_.count() < 0) return fleetgw::v1::BUS_STATE_SILENT;
  const Micros now = bus_.sim ? std::max(bus_now(), bus_.sim->virtual_now()) : bus_now();
  return now - last_frame_ts_ > core_.node().registry().config().offline_timeout
             ? fleetgw::v1::BUS_STATE_SILENT
             : fleetgw::v1::BUS_STATE_ACTIVE;
}

void Pipeline::answer_commands_at_stop() {
  for (const auto& payload : uplink_->take_commands()) {
    ++counters_.commands;
    commands_->answer_stopping(
        {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, bus_now());
  }
  for (const auto& busy : uplink_->take_busy_commands()) {
    ++counters_.commands;
    commands_->answer_busy(busy.command_id, busy.command_sha256, bus_now());
  }
}

void Pipeline::finish() {
  // Everything the trackers hold goes to the store, and a clean stop then drains the outbox
  // (the last telemetry batch included: it no longer waits for its batch delay) within the
  // grace, before the retained offline status.
  if (device_info_.due()) queue_device_info();
  recorder_->flush(bus_.replay ? last_frame_ts_ : bus_now());
  if (!uplink_) return;
  // The state the clean stop leaves retained (online = false) is the current one, not the last
  // one the throttle let through.
  if (state_throttle_.enabled()) {
    state_throttle_.touch();
    update_vehicle_state();
  }
  // Commands still queued, or arriving while the outbox drains, are answered shutting_down
  // (never run: the bus is stopped), so none is left without a result. What the drain does not
  // publish stays in the outbox for the next start.
  answer_commands_at_stop();
  uplink_->drain_for_stop();
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  while (Clock::now() < deadline && uplink_->state() == uplink::UplinkState::kConnected) {
    answer_commands_at_stop();
    if (outbox_.stats().depth == 0) break;
    uplink_->poll(system_now());
    uplink_->wait_for_events(std::chrono::milliseconds(50));
  }
  uplink_->stop(system_now());
  answer_commands_at_stop();
  const auto s = uplink_->stats();
  spdlog::info("uplink: {} records acked in {} messages, {} reconnects, {} still queued",
               s.acked_records, s.acked_messages, s.reconnects, outbox_.stats().depth);
}

}  // namespace fleetgw::runtime
