#include "gateway/can/replay_transport.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include <spdlog/spdlog.h>
#include <asio/post.hpp>

#include "gateway/can/error_frame.h"

namespace fleetgw::can {
namespace {

std::unique_ptr<std::istream> open_file(const std::filesystem::path& file) {
  auto in = std::make_unique<std::ifstream>(file, std::ios::binary);
  if (!*in) {
    throw std::runtime_error("cannot open replay file " + file.string() + ": " +
                             std::strerror(errno));
  }
  return in;
}

void validate(const ReplayOptions& o) {
  if (!(o.speed > 0.0)) {
    throw std::invalid_argument("replay speed must be > 0, got " + std::to_string(o.speed));
  }
  if (o.batch_size == 0) throw std::invalid_argument("replay batch_size must be > 0");
}

}  // namespace

ReplayTransport::ReplayTransport(asio::io_context& io, const std::filesystem::path& file,
                                 ReplayOptions options)
    : ReplayTransport(io, open_file(file), file.string(), std::move(options)) {}

ReplayTransport::ReplayTransport(asio::io_context& io, std::unique_ptr<std::istream> in,
                                 std::string source_name, ReplayOptions options)
    : io_(io),
      in_(std::move(in)),
      source_(std::move(source_name)),
      name_("replay:" + source_),
      options_(std::move(options)),
      reader_(*in_),
      timer_(io) {
  validate(options_);
  reader_.on_error([this](const candump::ParseError& e) {
    ++summary_.malformed_lines;
    spdlog::warn("replay {}: {}", source_, e.message);
  });
}

ReplayTransport::~ReplayTransport() {
  stop();
}

void ReplayTransport::start(FrameHandler on_frame, HealthHandler on_health) {
  if (started_) throw std::logic_error("ReplayTransport::start called twice");
  started_ = true;
  on_frame_ = std::move(on_frame);
  on_health_ = std::move(on_health);
  alive_ = std::make_shared<int>(0);
  running_ = true;
  start_time_ = std::chrono::steady_clock::now();
  set_state(ControllerState::kUp, "replaying " + source_);
  if (!running_) return;  // the health handler may have stopped us
  // Deliver from the io_context, never from inside start(): the caller may not be ready yet.
  asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
    if (token.expired()) return;
    schedule_next();
  });
}

bool ReplayTransport::send(const motinova::CanFrame& frame) {
  if (!running_) {
    ++health_.tx_failures;
    return false;
  }
  ++health_.tx_frames;
  if (options_.capture_sent) captured_.push_back(frame);
  return true;
}

void ReplayTransport::stop() {
  running_ = false;
  alive_.reset();
  timer_.cancel();
}

bool ReplayTransport::read_ahead() {
  if (!pending_) {
    pending_ = reader_.next();
    summary_.lines = reader_.line_number();
  }
  return pending_.has_value();
}

void ReplayTransport::schedule_next() {
  if (!running_) return;
  if (!read_ahead()) {
    finish();
    return;
  }
  if (options_.pace == ReplayOptions::Pace::kAsFastAsPossible) {
    run_batch();
    return;
  }
  const auto due = due_time(pending_->timestamp);
  if (due <= std::chrono::steady_clock::now()) {
    run_batch();
    return;
  }
  timer_.expires_at(due);
  timer_.async_wait([this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
    if (ec || token.expired()) return;
    run_batch();
  });
}

void ReplayTransport::run_batch() {
  // Delivers what is due now (all of it in fast mode) up to batch_size frames, then yields.
  const bool fast = options_.pace == ReplayOptions::Pace::kAsFastAsPossible;
  std::size_t n = 0;
  while (running_ && read_ahead()) {
    if (!fast && due_time(pending_->timestamp) > std::chrono::steady_clock::now()) {
      schedule_next();
      return;
    }
    candump::LogRecord rec = std::move(*pending_);
    pending_.reset();
    if (!deliver(rec)) return;
    if (++n >= options_.batch_size) {
      asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
        if (token.expired()) return;
        schedule_next();
      });
      return;
    }
  }
  if (running_ && !pending_) finish();
}

std::chrono::steady_clock::time_point ReplayTransport::due_time(motinova::Micros recorded) {
  if (!first_ts_) first_ts_ = recorded;
  // A log is not guaranteed to be sorted (merged captures); a frame recorded "earlier" than the
  // first is simply due immediately.
  const auto offset = std::max(motinova::Micros{0}, recorded - *first_ts_);
  return start_time_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                           std::chrono::duration<double, std::micro>(
                               static_cast<double>(offset.count()) / options_.speed));
}

bool ReplayTransport::deliver(const candump::LogRecord& rec) {
  if (!options_.interface.empty() && rec.interface != options_.interface) {
    ++summary_.filtered;
    return true;
  }
  if (rec.kind == candump::FrameKind::kError) {
    ++summary_.error_frames;
    ++health_.error_frames;
    const ErrorFrameInfo info = interpret_error_frame(rec.frame.id, rec.frame.payload());
    spdlog::info("replay {} line {}: CAN error frame: {}", source_, reader_.line_number(),
                 info.description);
    set_state(info.state.value_or(health_.state), info.description, /*force=*/true);
    return running_;
  }
  if (options_.acceptance_filter &&
      (!rec.is_standard_data() || !motinova::is_motinova_id(rec.frame.id))) {
    ++summary_.filtered;
    return true;
  }
  ++summary_.frames;
  ++health_.rx_frames;
  if (on_frame_) on_frame_(rec.frame, rec.timestamp);
  return running_;
}

void ReplayTransport::finish() {
  if (finished_) return;
  finished_ = true;
  running_ = false;
  spdlog::info("replay {}: end after {} lines, {} frames delivered, {} filtered, {} malformed",
               source_, summary_.lines, summary_.frames, summary_.filtered,
               summary_.malformed_lines);
  set_state(ControllerState::kDown, "end of replay " + source_);
  if (on_end_) on_end_(summary_);
}

void ReplayTransport::set_state(ControllerState s, std::string detail, bool force) {
  const bool changed = force || s != health_.state || detail != health_.detail;
  health_.state = s;
  health_.detail = std::move(detail);
  if (changed && on_health_) on_health_(health_);
}

}  // namespace fleetgw::can
