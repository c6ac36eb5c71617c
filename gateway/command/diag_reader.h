// DiagReader: runs one remote diagnostic read (issue 29) on the bus as the IoT node and turns
// the answer into a fleetgw.v1.DiagnosticResult. Journal, results and authentication stay with
// the CommandService (diag_service.cc); this part only talks to the bike.
//
// Contract:
//  * Clock-free and single-threaded like the CommandService: start(), on_message() and tick()
//    take `now` (bus timeline); request answers arrive inside IotNode::on_frame()/tick().
//  * Read-only: every frame it sends is a read request (mode 0x11, no data) submitted to the
//    node's RequestEngine, so it queues behind polls on the same ID and is retried every
//    `timing.retry_interval` and given up after `timing.timeout` (spec 3.7: 200 ms / 1 s, at
//    most 5 transmissions per request). Nothing is ever written to a node.
//  * The steps of a block run in order (mc_lifetime: record 1, then record 2). A required step
//    that gets no answer ends the read as TIMEOUT with reason "node_offline: ..." naming the
//    node, the request and the wait; an optional step that gets none leaves a note.
//  * A step without a request (mc_model: the spec defines no read) takes the node's latest
//    broadcast of the block when it is younger than `broadcast_fresh`, else waits for the next
//    one for at most `broadcast_wait` (then node_offline).
//  * One read at a time (busy()). Done runs exactly once per start(), after the reader is idle
//    again. Destroying the reader mid-read is safe: pending callbacks become no-ops.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/diag_blocks.h"
#include "gateway/node/iot_node.h"
#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::command {

struct DiagReaderConfig {
  motinova::DecodeOptions decode_options{};
  node::RequestTiming timing{};        // 200 ms retries, 1 s timeout (spec 3.7)
  Micros broadcast_wait{6'000'000};    // mc_model: the longest wait for a broadcast
  Micros broadcast_fresh{10'000'000};  // mc_model: a broadcast this young answers at once
};

struct DiagOutcome {
  v1::CommandResultCode code = v1::COMMAND_RESULT_CODE_UNSPECIFIED;
  std::string reason;  // "<code>: <detail>", empty on success
  v1::DiagnosticResult details;
};

class DiagReader {
 public:
  using Done = std::function<void(DiagOutcome outcome, Micros now)>;
  // Wall-clock microseconds of the bus-timeline instant `heard`, at bus time `now` (for
  // DiagnosticMessage.heard_at_us).
  using WallOf = std::function<std::int64_t(Micros heard, Micros now)>;

  DiagReader(DiagReaderConfig config, node::IotNode& node);
  ~DiagReader();
  DiagReader(const DiagReader&) = delete;
  DiagReader& operator=(const DiagReader&) = delete;

  void start(DiagBlockSpec spec, Micros now, WallOf wall, Done done);
  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  bool busy() const { return job_ != nullptr; }
  const DiagReaderConfig& config() const { return config_; }

 private:
  struct Job;
  void run_step(Micros now);
  void on_answer(const node::RequestResult& res);
  void take(const motinova::AppFrame& frame, Micros heard, Micros now);
  void missing(Micros waited, int transmissions, Micros now);
  void finish(v1::CommandResultCode code, std::string reason, Micros now);

  DiagReaderConfig config_;
  node::IotNode& node_;
  std::shared_ptr<Job> job_;  // shared so node callbacks can tell it is gone
};

}  // namespace fleetgw::command
