// The MC actions of issue 13 on the bus: preflight, the writes, and their confirmation from the
// settings report (speed limit), the running data (assist, headlight, trip) or the READY
// replies (power off). See mc_actions.h for the rules.
#include "gateway/command/mc_actions.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/common/untrusted_text.h"
#include "gateway/node/messages.h"
#include "motinova/catalogue.h"

namespace fleetgw::command {
namespace {

constexpr std::uint8_t kFnAssistLight = 0x30;    // 0x761/0x3002
constexpr std::uint8_t kFnWriteSettings = 0x34;  // 0x761/0x3408
constexpr std::uint8_t kFnClear = 0x36;          // 0x761/0x3605
constexpr std::uint8_t kFnMcStatus = 0x10;       // 0x710/0x1020
constexpr std::int64_t kLightOn = 0xF1;

std::int64_t ms_of(Micros d) {
  return d.count() / 1000;
}

Rejection refuse(RejectReason reason, std::string detail) {
  return Rejection{reason, std::move(detail), {}, true};
}

}  // namespace

// What a settings report (0x5408) says, in the wire values the write copies back.
struct McActionRunner::Settings {
  std::int64_t factory_kmh = 0;
  std::int64_t offset_kmh = 0;
  std::int64_t wheel_adjust_raw = 0;
  std::int64_t mode_raw = 0;
  std::int64_t limit_kmh() const { return factory_kmh + offset_kmh; }
};

// The parts of the running data (0x1020) the actions confirm from.
struct McActionRunner::Running {
  std::int64_t assist = 0;
  bool light_on = false;
  std::int64_t trip_dm = 0;  // 0.1 km
  std::int64_t trip_s = 0;
  Micros at{0};
};

struct McActionRunner::Job {
  enum class Phase : std::uint8_t { kReadBefore, kVerify, kWaitRunning, kShutdown };
  McRequest request;
  Done done;
  Phase phase = Phase::kReadBefore;
  Micros started{0};
  Micros write_sent{0};
  int writes = 0;
  int rereads = 0;  // verification reads repeated after a stale-looking report (see on_settings)
  // Speed limit: what is written (the limit in force with the request), and the write, built
  // from the first report.
  std::int64_t write_kmh = 0;
  std::optional<Settings> before;
  std::int64_t target_offset = 0;
  // Assist / headlight: both halves of 0x3002.
  std::int64_t target_assist = 0;
  bool target_light = false;
  std::optional<Running> seen_after_write;
  v1::McActionResult details;
};

McActionRunner::McActionRunner(McActionConfig config, node::IotNode& node, MotionInterlock& motion)
    : config_(std::move(config)), node_(node), motion_(motion) {}

McActionRunner::~McActionRunner() = default;

std::optional<std::uint8_t> McActionRunner::assist_value(std::string_view name) const {
  for (const auto& a : config_.decode_options.assist_names) {
    if (a.name == name) return a.value;
  }
  return std::nullopt;
}

std::string McActionRunner::assist_name(std::int64_t raw) const {
  for (const auto& a : config_.decode_options.assist_names) {
    if (a.value == raw) return a.name;
  }
  return fmt::format("0x{:02X}", raw);
}

std::optional<McActionRunner::Running> McActionRunner::latest_running(Micros now) const {
  const auto* snap =
      node_.registry().node(motinova::Node::kMc).find(node::ids::kMcBroadcast, kFnMcStatus);
  if (snap == nullptr || now - snap->received > config_.state_max_age) return std::nullopt;
  motinova::DecodedMessage m;
  motinova::decode(snap->frame, motinova::Catalogue::standard(), config_.decode_options, m);
  if (m.status != motinova::DecodeStatus::kOk) return std::nullopt;
  const auto assist = m.raw("assist");
  const auto light = m.raw("headlight");
  if (!assist || !light) return std::nullopt;
  return Running{*assist, *light == kLightOn, m.raw("trip_km").value_or(0),
                 m.raw("trip_time_s").value_or(0), snap->received};
}

std::optional<McActionRunner::Settings> McActionRunner::settings_from(
    const motinova::AppFrame& frame) const {
  motinova::DecodedMessage m;
  motinova::decode(frame, motinova::Catalogue::standard(), config_.decode_options, m);
  if (m.status != motinova::DecodeStatus::kOk || m.name() != "mc_settings") return std::nullopt;
  const auto limit = m.raw("speed_limit_kmh");
  const auto offset = m.raw("speed_limit_offset_kmh");
  const auto adjust = m.raw("wheel_adjust_cm");
  const auto mode = m.raw("mode");
  if (!limit || !offset || !adjust || !mode) return std::nullopt;
  Settings s;
  s.offset_kmh = *offset;
  s.factory_kmh = config_.settings_limit_is_factory ? *limit : *limit - *offset;
  s.wheel_adjust_raw = *adjust;
  s.mode_raw = *mode;
  return s;
}

// The latest settings report heard from the MC (the poller reads it every 60 s), if any.
std::optional<McActionRunner::Settings> McActionRunner::latest_settings() const {
  const auto& mc = node_.registry().node(motinova::Node::kMc);
  const node::MessageSnapshot* best = nullptr;
  for (const std::uint16_t id :
       {node::ids::kMcToObc, node::ids::kMcBroadcast, node::ids::kMcToIot}) {
    const auto* s = mc.find(id, node::fn::kMcSettings);
    if (s != nullptr && (best == nullptr || s->received > best->received)) best = s;
  }
  if (best == nullptr) return std::nullopt;
  return settings_from(best->frame);
}

bool McActionRunner::lock_moving(Micros now) const {
  if (node_.locks().any_busy()) return true;
  for (int k = 0; k < motinova::kLockCount; ++k) {
    const auto* snap = node_.registry()
                           .node(motinova::lock_node(k))
                           .find(node::ids::lock_broadcast_id(k), node::fn::kLockStatus);
    if (snap == nullptr || now - snap->received > config_.lock_motion_max_age) continue;
    const auto state = node::lock_state_of(snap->frame, k);
    if (state == node::lock_state::kUnlocking || state == node::lock_state::kLocking) return true;
  }
  return false;
}

std::optional<Rejection> McActionRunner::preflight(const McRequest& req, bool lock_command_running,
                                                   Micros now) {
  if (node_.shutdown_running()) {
    return refuse(RejectReason::kShuttingDown, "the gateway is shutting the bike down");
  }
  if (!node_.registry().online(motinova::Node::kMc)) {
    return refuse(RejectReason::kMcOffline, "the motor controller (node 1) is offline");
  }
  if (busy()) return refuse(RejectReason::kMcBusy, "another MC action is executing");
  switch (req.kind) {
    case McActionKind::kSpeedLimit:
      // 0 would switch the motor's help off through the back door: assist_level does that.
      if (req.speed_limit_kmh == 0) {
        return refuse(RejectReason::kOutOfRange, "0 km/h is not a speed limit (1..255)");
      }
      // Checked again on the fresh report; a known factory limit refuses without a read.
      if (const auto s = latest_settings()) {
        const std::int64_t want = req.speed_limit_kmh;
        const std::int64_t lo = std::max<std::int64_t>(1, s->factory_kmh - config_.max_offset_kmh);
        if (want < lo || want > s->factory_kmh) {
          return refuse(RejectReason::kOutOfRange,
                        fmt::format("{} km/h is outside the MC's range {}..{} km/h",
                                    req.speed_limit_kmh, lo, s->factory_kmh));
        }
      }
      return std::nullopt;
    case McActionKind::kAssistLevel:
      if (!assist_value(req.assist_level)) {
        return refuse(RejectReason::kUnknownAssistLevel,
                      "'" + common::untrusted_excerpt(req.assist_level, 64) +
                          "' is not a configured assist level");
      }
      [[fallthrough]];
    case McActionKind::kHeadlight:
    case McActionKind::kClearTrip:
      if (!latest_running(now)) {
        return refuse(RejectReason::kMcStateUnknown,
                      fmt::format("no MC running data (0x710/0x1020) within {} ms",
                                  ms_of(config_.state_max_age)));
      }
      return std::nullopt;
    case McActionKind::kPowerOff: {
      if (lock_command_running || lock_moving(now)) {
        return refuse(RejectReason::kLockMoving, "will not power off while a lock is moving");
      }
      const auto m = motion_.moving(node_.registry(), now);
      if (!m) {
        return refuse(RejectReason::kInterlockMotionUnknown,
                      "will not power off: no recent mc_status, motion unknown");
      }
      if (*m)
        return refuse(RejectReason::kInterlockMoving, "will not power off while the bike moves");
      return std::nullopt;
    }
    case McActionKind::kNone:
      break;
  }
  return refuse(RejectReason::kMalformed, "not an MC action");
}

void McActionRunner::start(const McRequest& req, Micros now, Done done) {
  job_ = std::make_shared<Job>();
  Job& j = *job_;
  j.request = req;
  j.done = std::move(done);
  j.started = now;
  j.details.set_action(std::string(mc_action_name(req.kind)));
  switch (req.kind) {
    case McActionKind::kSpeedLimit: {
      // A remote command asks for a cap; the MC is given the limit in force with it.
      const auto in_force = req.sets_operator_cap
                                ? speed_.in_force_with_cap(static_cast<int>(req.speed_limit_kmh))
                                : std::nullopt;
      j.write_kmh = in_force.value_or(static_cast<int>(req.speed_limit_kmh));
      j.phase = Job::Phase::kReadBefore;
      read_settings(now);
      return;
    }
    case McActionKind::kAssistLevel:
    case McActionKind::kHeadlight:
    case McActionKind::kClearTrip: {
      const auto r = latest_running(now);
      if (!r) {
        finish(v1::COMMAND_RESULT_CODE_FAILED, "mc_state_unknown: no recent MC running data", now);
        return;
      }
      j.target_assist = req.kind == McActionKind::kAssistLevel
                            ? assist_value(req.assist_level).value_or(r->assist)
                            : r->assist;
      j.target_light = req.kind == McActionKind::kHeadlight ? req.headlight_on : r->light_on;
      write(now);
      return;
    }
    case McActionKind::kPowerOff: {
      j.phase = Job::Phase::kShutdown;
      std::weak_ptr<Job> weak = job_;
      const bool started =
          node_.start_shutdown_observed(now, [this, weak](const node::ShutdownOutcome& o) {
            const auto job = weak.lock();
            if (!job || job != job_) return;
            job->details.set_mc_ready(o.mc_ready);
            if (o.awaited_obc) job->details.set_obc_ready(o.obc_ready);
            const Micros at = job->started + o.elapsed;
            const int awaited = int{o.awaited_mc} + int{o.awaited_obc};
            const int ready = int{o.awaited_mc && o.mc_ready} + int{o.awaited_obc && o.obc_ready};
            if (ready == awaited) {
              finish(v1::COMMAND_RESULT_CODE_SUCCEEDED, {}, at);
            } else if (ready == 0) {
              finish(v1::COMMAND_RESULT_CODE_TIMEOUT, "no_answer: no READY after SHUTDOWN", at);
            } else {
              finish(v1::COMMAND_RESULT_CODE_FAILED,
                     std::string("not_confirmed: no READY from the ") +
                         (o.mc_ready ? "OBC" : "MC") + " after SHUTDOWN",
                     at);
            }
          });
      if (!started && job_ && job_->phase == Job::Phase::kShutdown) {
        finish(v1::COMMAND_RESULT_CODE_FAILED, "shutting_down: a shutdown is already running", now);
      }
      return;
    }
    case McActionKind::kNone:
      break;
  }
  finish(v1::COMMAND_RESULT_CODE_FAILED, "malformed: not an MC action", now);
}

void McActionRunner::read_settings(Micros now) {
  node::Request r;
  r.frame = node::read_request(node::ids::kIotToMc, node::fn::kMcReadSettings);
  // U14: the MC's answer may come on 0x713 (best guess), 0x710 or 0x716.
  r.answers = {{node::ids::kMcToObc, node::fn::kMcSettings},
               {node::ids::kMcBroadcast, node::fn::kMcSettings},
               {node::ids::kMcToIot, node::fn::kMcSettings}};
  std::weak_ptr<Job> weak = job_;
  node_.requests().submit(
      std::move(r),
      [this, weak](const node::RequestResult& res) {
        const auto job = weak.lock();
        if (job && job == job_) on_settings(res);
      },
      now);
}

void McActionRunner::on_settings(const node::RequestResult& res) {
  Job& j = *job_;
  const Micros now = res.completed;
  if (res.outcome == node::RequestOutcome::kTimedOut) {
    finish(v1::COMMAND_RESULT_CODE_TIMEOUT,
           fmt::format("no_answer: the MC did not answer the settings read (0x3300) within {} ms",
                       ms_of(res.latency)),
           now);
    return;
  }
  if (res.outcome != node::RequestOutcome::kAnswered || !res.answered_by) {
    finish(v1::COMMAND_RESULT_CODE_FAILED, "send_failed: the settings read could not be sent", now);
    return;
  }
  // The registry took the answer before the request engine saw it (IotNode::on_frame).
  const auto* snap = node_.registry()
                         .node(motinova::Node::kMc)
                         .find(res.answered_by->can_id, res.answered_by->function);
  const auto s = snap != nullptr ? settings_from(snap->frame) : std::nullopt;
  if (!s) {
    finish(v1::COMMAND_RESULT_CODE_FAILED, "not_confirmed: unreadable MC settings report", now);
    return;
  }
  j.details.set_factory_speed_limit_kmh(
      static_cast<std::uint32_t>(std::max<std::int64_t>(0, s->factory_kmh)));
  j.details.set_speed_limit_kmh(
      static_cast<std::uint32_t>(std::max<std::int64_t>(0, s->limit_kmh())));
  const std::int64_t want = j.request.speed_limit_kmh;
  if (j.phase == Job::Phase::kReadBefore) {
    const std::int64_t lo = std::max<std::int64_t>(1, s->factory_kmh - config_.max_offset_kmh);
    for (const std::int64_t kmh : {want, j.write_kmh}) {
      if (kmh < lo || kmh > s->factory_kmh) {
        finish(v1::COMMAND_RESULT_CODE_REJECTED,
               fmt::format("out_of_range: {} km/h{} is outside the MC's range {}..{} km/h", kmh,
                           kmh == want ? "" : " (the limit in force)", lo, s->factory_kmh),
               now);
        return;
      }
    }
    j.before = s;
    j.target_offset = j.write_kmh - s->factory_kmh;
    // Already in force: written only when it changes.
    if (s->offset_kmh == j.target_offset) {
      finish(v1::COMMAND_RESULT_CODE_SUCCEEDED, {}, now);
      return;
    }
    write(now);
    return;
  }
  // Verification read after a write.
  if (s->offset_kmh == j.target_offset) {
    finish(v1::COMMAND_RESULT_CODE_SUCCEEDED, {}, now);
    return;
  }
  // A report that still shows the offset from before the write may be the late answer to an
  // earlier read the request engine retried (a slow MC answers the first try and the retry):
  // the reply carries no request id, so read once more before concluding the write was lost.
  if (j.before && s->offset_kmh == j.before->offset_kmh && j.rereads < j.writes) {
    ++j.rereads;
    read_settings(now);
    return;
  }
  if (j.writes <= config_.retries) {
    spdlog::warn("MC action speed_limit: MC reports offset {} instead of {}; writing again",
                 s->offset_kmh, j.target_offset);
    write(now);
    return;
  }
  finish(v1::COMMAND_RESULT_CODE_FAILED,
         fmt::format("not_confirmed: the MC reports a limit of {} km/h (offset {}) after {} "
                     "write(s) of offset {}",
                     s->limit_kmh(), s->offset_kmh, j.writes, j.target_offset),
         now);
}

void McActionRunner::write(Micros now) {
  Job& j = *job_;
  const auto& cat = motinova::Catalogue::standard();
  motinova::AppFrame frame;
  switch (j.request.kind) {
    case McActionKind::kSpeedLimit:
      frame = motinova::MessageWriter(*cat.find(node::ids::kIotToMc, kFnWriteSettings),
                                      config_.decode_options)
                  .raw("wheel_adjust_cm", j.before->wheel_adjust_raw)
                  .raw("mode", j.before->mode_raw)
                  .raw("speed_limit_offset_kmh", j.target_offset)
                  .frame();
      break;
    case McActionKind::kAssistLevel:
    case McActionKind::kHeadlight:
      frame = motinova::MessageWriter(*cat.find(node::ids::kIotToMc, kFnAssistLight),
                                      config_.decode_options)
                  .raw("assist", j.target_assist)
                  .boolean("headlight", j.target_light)
                  .frame();
      break;
    case McActionKind::kClearTrip:
      frame = node::keyword_frame(node::ids::kIotToMc, motinova::Mode::kWrite, kFnClear, "CLEAR");
      break;
    default:
      finish(v1::COMMAND_RESULT_CODE_FAILED, "malformed: nothing to write", now);
      return;
  }
  node::Request r;
  r.frame = frame;  // no answers: sent once (spec: IOT writes are not acknowledged)
  std::weak_ptr<Job> weak = job_;
  node_.requests().submit(
      std::move(r),
      [this, weak](const node::RequestResult& res) {
        const auto job = weak.lock();
        if (!job || job != job_) return;
        if (res.outcome != node::RequestOutcome::kSent) {
          finish(v1::COMMAND_RESULT_CODE_FAILED, "send_failed: the write could not be sent",
                 res.completed);
          return;
        }
        ++job->writes;
        job->details.set_writes_sent(static_cast<std::uint32_t>(job->writes));
        job->write_sent = res.completed;
        job->seen_after_write.reset();
        if (job->request.kind == McActionKind::kSpeedLimit) {
          job->phase = Job::Phase::kVerify;
          read_settings(res.completed);
        } else {
          job->phase = Job::Phase::kWaitRunning;
        }
      },
      now);
}

bool McActionRunner::confirmed(const Running& r, Micros now) const {
  const Job& j = *job_;
  if (j.request.kind == McActionKind::kClearTrip) {
    const std::int64_t since_s = (now - j.write_sent).count() / 1'000'000 + 1;
    return r.trip_dm <= config_.trip_cleared_max_dm && r.trip_s <= since_s;
  }
  return r.assist == j.target_assist && r.light_on == j.target_light;
}

void McActionRunner::record(const Running& r) {
  Job& j = *job_;
  if (j.request.kind == McActionKind::kClearTrip) {
    j.details.set_trip_m(static_cast<std::uint32_t>(std::max<std::int64_t>(0, r.trip_dm) * 100));
  } else {
    j.details.set_assist_level(assist_name(r.assist));
    j.details.set_headlight_on(r.light_on);
  }
}

void McActionRunner::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (!job_ || job_->phase != Job::Phase::kWaitRunning) return;
  if (msg.status != motinova::DecodeStatus::kOk || msg.name() != "mc_status") return;
  if (now < job_->write_sent) return;
  const auto assist = msg.raw("assist");
  const auto light = msg.raw("headlight");
  if (!assist || !light) return;
  const Running r{*assist, *light == kLightOn, msg.raw("trip_km").value_or(0),
                  msg.raw("trip_time_s").value_or(0), now};
  job_->seen_after_write = r;
  record(r);
  if (confirmed(r, now)) {
    finish(v1::COMMAND_RESULT_CODE_SUCCEEDED, {}, now);
    return;
  }
  if (now - job_->write_sent >= config_.confirm_timeout) attempt_over(now);
}

void McActionRunner::tick(Micros now) {
  if (!job_ || job_->phase != Job::Phase::kWaitRunning) return;
  if (now - job_->write_sent >= config_.confirm_timeout) attempt_over(now);
}

// The confirmation window of a running-data action closed without a match.
void McActionRunner::attempt_over(Micros now) {
  Job& j = *job_;
  if (j.writes <= config_.retries) {
    spdlog::warn("MC action {}: not confirmed within {} ms; writing again ({}/{})",
                 mc_action_name(j.request.kind), ms_of(config_.confirm_timeout), j.writes,
                 config_.retries);
    write(now);
    return;
  }
  if (!j.seen_after_write) {
    finish(v1::COMMAND_RESULT_CODE_TIMEOUT,
           fmt::format("no_answer: no MC running data within {} ms of the write",
                       ms_of(config_.confirm_timeout)),
           now);
    return;
  }
  const Running& r = *j.seen_after_write;
  std::string shows;
  if (j.request.kind == McActionKind::kClearTrip) {
    shows =
        fmt::format("a trip of {:.1f} km, {} s", static_cast<double>(r.trip_dm) / 10.0, r.trip_s);
  } else {
    shows =
        fmt::format("assist {}, headlight {}", assist_name(r.assist), r.light_on ? "on" : "off");
  }
  finish(v1::COMMAND_RESULT_CODE_FAILED,
         fmt::format("not_confirmed: the MC shows {} after {} write(s)", shows, j.writes), now);
}

void McActionRunner::finish(v1::CommandResultCode code, std::string reason, Micros now) {
  // Idle before Done runs, so Done may start the next action.
  const std::shared_ptr<Job> job = std::move(job_);
  job_.reset();
  McOutcome out{code, std::move(reason), std::move(job->details)};
  if (job->done) job->done(std::move(out), now);
}

}  // namespace fleetgw::command
