// One remote diagnostic read on the bus (issue 29): the steps of a block, their answers taken
// from the node registry, the node_offline outcome. See diag_reader.h.
#include "gateway/command/diag_reader.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace fleetgw::command {

struct DiagReader::Job {
  DiagBlockSpec spec;
  std::size_t step = 0;
  Done done;
  WallOf wall;
  v1::DiagnosticResult details;
  Micros started{0};
  bool waiting_broadcast = false;
  Micros wait_started{0};
};

DiagReader::DiagReader(DiagReaderConfig config, node::IotNode& node)
    : config_(std::move(config)), node_(node) {}

DiagReader::~DiagReader() = default;

void DiagReader::start(DiagBlockSpec spec, Micros now, WallOf wall, Done done) {
  job_ = std::make_shared<Job>();
  job_->spec = std::move(spec);
  job_->done = std::move(done);
  job_->wall = std::move(wall);
  job_->started = now;
  job_->details.set_block(std::string(job_->spec.name));
  job_->details.set_node(std::string(motinova::node_name(job_->spec.node)));
  job_->details.set_source("bus");
  run_step(now);
}

void DiagReader::run_step(Micros now) {
  Job& j = *job_;
  if (j.step >= j.spec.steps.size()) {
    finish(v1::COMMAND_RESULT_CODE_SUCCEEDED, {}, now);
    return;
  }
  const DiagStep& step = j.spec.steps[j.step];
  if (step.request_id == 0) {
    // No read exists for this block: its latest broadcast, or the next one.
    const auto& key = step.answers.front();
    const auto* snap =
        node_.registry().node(motinova::source_of(key.can_id)).find(key.can_id, key.function);
    if (snap != nullptr && now - snap->received <= config_.broadcast_fresh) {
      take(snap->frame, snap->received, now);
      return;
    }
    j.waiting_broadcast = true;
    j.wait_started = now;
    return;
  }
  node::Request r;
  r.frame = node::read_request(step.request_id, step.request_function);
  r.answers = step.answers;
  r.timing = config_.timing;
  std::weak_ptr<Job> weak = job_;
  node_.requests().submit(
      std::move(r),
      [this, weak](const node::RequestResult& res) {
        const auto job = weak.lock();
        if (job && job == job_) on_answer(res);
      },
      now);
}

void DiagReader::on_answer(const node::RequestResult& res) {
  Job& j = *job_;
  const Micros now = res.completed;
  j.details.set_requests_sent(j.details.requests_sent() +
                              static_cast<std::uint32_t>(res.transmissions));
  if (res.outcome == node::RequestOutcome::kTimedOut) {
    missing(res.latency, res.transmissions, now);
    return;
  }
  if (res.outcome != node::RequestOutcome::kAnswered || !res.answered_by) {
    finish(v1::COMMAND_RESULT_CODE_FAILED, "send_failed: the read request could not be sent", now);
    return;
  }
  // The registry took the answer before the request engine saw it (IotNode::on_frame).
  const auto& by = *res.answered_by;
  const auto* snap =
      node_.registry().node(motinova::source_of(by.can_id)).find(by.can_id, by.function);
  if (snap == nullptr) {
    finish(v1::COMMAND_RESULT_CODE_FAILED, "not_confirmed: the answer was not kept", now);
    return;
  }
  take(snap->frame, snap->received, now);
}

void DiagReader::take(const motinova::AppFrame& frame, Micros heard, Micros now) {
  Job& j = *job_;
  j.waiting_broadcast = false;
  decode_diag_message(frame, config_.decode_options, j.wall(heard, now), *j.details.add_messages());
  ++j.step;
  run_step(now);
}

// A step got no answer: optional ones leave a note, required ones end the read.
void DiagReader::missing(Micros waited, int transmissions, Micros now) {
  Job& j = *job_;
  const DiagStep& step = j.spec.steps[j.step];
  const std::string what =
      step.request_id == 0
          ? fmt::format("did not broadcast {} ({}) within {} ms", step.answer_name,
                        diag_request_text(step), waited.count() / 1000)
          : fmt::format("did not answer the read {} within {} ms ({} request(s))",
                        diag_request_text(step), waited.count() / 1000, transmissions);
  if (step.optional && j.details.messages_size() > 0) {
    j.details.set_note(j.details.note() + (j.details.note().empty() ? "" : "; ") +
                       std::string(step.answer_name) +
                       " not answered: " + diag_node_text(j.spec.node) + " " + what);
    ++j.step;
    run_step(now);
    return;
  }
  finish(v1::COMMAND_RESULT_CODE_TIMEOUT,
         "node_offline: " + diag_node_text(j.spec.node) + " " + what, now);
}

void DiagReader::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (!job_ || !job_->waiting_broadcast || msg.frame == nullptr) return;
  const DiagStep& step = job_->spec.steps[job_->step];
  for (const auto& key : step.answers) {
    if (key.matches(*msg.frame)) {
      take(*msg.frame, now, now);
      return;
    }
  }
}

void DiagReader::tick(Micros now) {
  if (!job_ || !job_->waiting_broadcast) return;
  if (now - job_->wait_started >= config_.broadcast_wait) {
    job_->waiting_broadcast = false;
    missing(now - job_->wait_started, 0, now);
  }
}

void DiagReader::finish(v1::CommandResultCode code, std::string reason, Micros now) {
  // Idle before Done runs, so Done may start the next read.
  const std::shared_ptr<Job> job = std::move(job_);
  job_.reset();
  if (code != v1::COMMAND_RESULT_CODE_SUCCEEDED) {
    spdlog::info("diagnostics: {} read ended: {}", job->spec.name, reason);
  }
  DiagOutcome out{code, std::move(reason), std::move(job->details)};
  if (job->done) job->done(std::move(out), now);
}

}  // namespace fleetgw::command
