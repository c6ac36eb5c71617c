// A candump -L recording played back as the CAN bus.
//
// Contract:
//  * Frames are delivered on the io_context thread with the timestamps recorded in the file (the
//    replay's virtual timeline), in file order.
//  * Pace::kRecorded reproduces the recorded gaps, divided by `speed` (2.0 = twice as fast),
//    scheduled against absolute steady-clock deadlines so delays do not accumulate.
//    Pace::kAsFastAsPossible delivers `batch_size` frames per posted handler, so timers and
//    other I/O on the same io_context still run during a long replay.
//  * Like the SocketCAN acceptance filter, only standard data frames 0x700-0x7FF are delivered
//    (unless ReplayOptions::acceptance_filter is false); other frames are counted as filtered.
//    Error frames in the log update health() exactly as on a live bus.
//  * Malformed lines are logged (spdlog, with line number) and counted, and the replay goes on.
//  * At the end of the file the link goes kDown ("end of replay") and the end handler runs once.
//  * send() never touches the file: it records the frame in captured() when capture is on and
//    returns true while the replay is running. stop() halts delivery; no handler runs after it.
//  * Single-threaded: all member functions must be called on the io_context's thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <istream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <asio/io_context.hpp>
#include <asio/steady_timer.hpp>

#include "gateway/can/candump.h"
#include "gateway/can/transport.h"

namespace fleetgw::can {

struct ReplayOptions {
  enum class Pace : uint8_t { kRecorded, kAsFastAsPossible };
  Pace pace = Pace::kAsFastAsPossible;
  double speed = 1.0;  // kRecorded only; must be > 0
  // Frames per handler before yielding to the io_context. The pipeline flushes the recorder
  // between handlers: 8,192 frames (~4 ms of CPU here) keep timers timely and make a fast
  // replay of the worst-case hour commit ~60 times instead of ~250 (2,048 frames): 0.46 against
  // 0.55 s of CPU, since every commit rewrites the B-trees' rightmost pages into the WAL.
  std::size_t batch_size = 8192;
  std::string interface;          // only replay lines of this interface; empty = all
  bool acceptance_filter = true;  // deliver only standard data frames 0x700-0x7FF
  bool capture_sent = false;      // keep frames passed to send() in captured()
};

struct ReplaySummary {
  uint64_t lines = 0;            // lines read
  uint64_t frames = 0;           // frames delivered
  uint64_t filtered = 0;         // well-formed frames not delivered (filter, other interface)
  uint64_t error_frames = 0;     // CAN error frames in the log
  uint64_t malformed_lines = 0;  // lines rejected by the parser (incl. unsupported CAN FD)
};

class ReplayTransport final : public Transport {
 public:
  using EndHandler = std::function<void(const ReplaySummary&)>;

  // Opens `file`; throws std::runtime_error naming the file and the reason if it cannot be read,
  // std::invalid_argument for bad options.
  ReplayTransport(asio::io_context& io, const std::filesystem::path& file, ReplayOptions options);
  // Plays an already open stream; `source_name` names it in log messages.
  ReplayTransport(asio::io_context& io, std::unique_ptr<std::istream> in, std::string source_name,
                  ReplayOptions options);
  ~ReplayTransport() override;

  ReplayTransport(const ReplayTransport&) = delete;
  ReplayTransport& operator=(const ReplayTransport&) = delete;

  // Set before start().
  void on_end(EndHandler handler) { on_end_ = std::move(handler); }

  void start(FrameHandler on_frame, HealthHandler on_health) override;
  bool send(const motinova::CanFrame& frame) override;
  void stop() override;
  const BusHealth& health() const override { return health_; }
  std::string_view name() const override { return name_; }

  const ReplaySummary& summary() const { return summary_; }
  const std::vector<candump::ParseError>& errors() const { return reader_.errors(); }
  const std::vector<motinova::CanFrame>& captured() const { return captured_; }
  bool finished() const { return finished_; }

 private:
  void schedule_next();
  void run_batch();
  // Delivers `rec` (or counts it); returns false when the transport was stopped meanwhile.
  bool deliver(const candump::LogRecord& rec);
  bool read_ahead();
  void finish();
  // Reports through the health handler when something changed (or always, with force).
  void set_state(ControllerState s, std::string detail, bool force = false);
  std::chrono::steady_clock::time_point due_time(motinova::Micros recorded);

  asio::io_context& io_;
  std::unique_ptr<std::istream> in_;
  std::string source_;
  std::string name_;
  ReplayOptions options_;
  candump::LineReader reader_;
  asio::steady_timer timer_;

  FrameHandler on_frame_;
  HealthHandler on_health_;
  EndHandler on_end_;
  BusHealth health_;
  ReplaySummary summary_;
  std::vector<motinova::CanFrame> captured_;

  std::optional<candump::LogRecord> pending_;  // next record to deliver
  std::optional<motinova::Micros> first_ts_;
  std::chrono::steady_clock::time_point start_time_;
  bool started_ = false;
  bool running_ = false;
  bool finished_ = false;
  // Handlers posted to the io_context hold a weak reference: once the transport is stopped or
  // destroyed they find it expired and return without touching `this`.
  std::shared_ptr<int> alive_;
};

}  // namespace fleetgw::can
