// Request/answer bookkeeping for everything the IoT node asks of other nodes (spec §3.7):
// retries every 200 ms, gives up after 1 s, matches answers that arrive on broadcast IDs, and
// keeps at most one request outstanding per target CAN ID.
//
// Contract:
//  * submit() queues a request behind the ones already waiting for the same target ID (FIFO);
//    only the head of each per-ID queue is on the bus. It is sent at once when its ID is idle,
//    otherwise as soon as the request ahead of it completes. So two requests (and thus two
//    segmented messages) are never in flight on one ID, and a node is never asked two things at
//    once.
//  * A request with expected answers is re-sent every `retry_interval` after its previous
//    transmission and completes as kAnswered on the first frame, received after its first
//    transmission, whose (CAN ID, function) is among its answers (whoever triggered it: a cyclic
//    broadcast of the block answers the read just as well). It completes as kTimedOut when
//    `timeout` has passed since the first transmission; no transmission happens at that tick.
//    With the defaults that is exactly 5 transmissions (t = 0, 200, 400, 600, 800 ms).
//  * A request without answers (a write such as LOCK) is sent once when it reaches the head of
//    its queue and completes as kSent (or kSendFailed if the sender refused it) at once.
//  * A refused transmission of a request with answers counts as an attempt; the retry timer
//    handles it like a lost frame.
//  * Callbacks run after the engine's state is consistent; they may submit() or cancel()
//    (re-entrancy is safe). cancel() of a queued or outstanding request completes it as
//    kCancelled without calling its callback.
//  * Time only advances through the `now` arguments; tick() must run at next_event() (retries
//    and timeouts are then exact) or at least every 20-50 ms (late by at most one period).
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "gateway/node/frame_sender.h"
#include "gateway/node/messages.h"
#include "motinova/can.h"
#include "motinova/frame.h"

namespace fleetgw::node {

using motinova::Micros;
using RequestId = uint64_t;

enum class RequestOutcome : uint8_t { kAnswered, kTimedOut, kSent, kSendFailed };
std::string_view request_outcome_name(RequestOutcome o);  // "answered", "timed_out", ...

struct RequestResult {
  RequestId id = 0;
  RequestOutcome outcome = RequestOutcome::kTimedOut;
  uint16_t target_id = 0;
  int transmissions = 0;                  // how often the request went on the bus
  Micros latency{0};                      // answer time (or give-up time) - first transmission
  Micros completed{0};                    // `now` at completion
  std::optional<MessageKey> answered_by;  // the answer's (ID, function)
};

struct RequestTiming {
  Micros retry_interval{200'000};
  Micros timeout{1'000'000};
};

struct Request {
  motinova::AppFrame frame;         // what to send; frame.can_id is the target ID
  std::vector<MessageKey> answers;  // empty: fire-and-forget write
  RequestTiming timing;
};

struct RequestEngineStats {
  uint64_t transmissions = 0;
  uint64_t send_failures = 0;
  uint64_t answered = 0;
  uint64_t timed_out = 0;
};

class RequestEngine {
 public:
  using Callback = std::function<void(const RequestResult&)>;

  explicit RequestEngine(FrameSender& sender) : sender_(sender) {}
  RequestEngine(const RequestEngine&) = delete;
  RequestEngine& operator=(const RequestEngine&) = delete;

  RequestId submit(Request request, Callback on_done, Micros now);
  // Drops a queued or outstanding request; its callback is not called. Returns false if the id
  // is unknown (already completed).
  bool cancel(RequestId id, Micros now);

  void on_frame(const motinova::AppFrame& frame, Micros now);
  void tick(Micros now);
  // The earliest retry or timeout of an outstanding request (Micros::max(): none). tick() at
  // that time does the work; queued requests start when the one ahead completes.
  Micros next_event() const;

  // True when a request to `target_id` is on the bus (waiting for its answer).
  bool busy(uint16_t target_id) const;
  // True while `id` waits in a queue behind another request (not yet transmitted).
  bool queued(RequestId id) const;
  std::size_t pending(uint16_t target_id) const;  // outstanding + queued
  std::size_t pending() const;
  const RequestEngineStats& stats() const { return stats_; }

 private:
  struct Pending {
    RequestId id = 0;
    Request request;
    Callback on_done;
    int transmissions = 0;
    Micros first_sent{0};
    Micros last_sent{0};
  };
  struct Channel {
    std::optional<Pending> active;
    std::deque<Pending> queue;
  };
  using Completion = std::pair<Callback, RequestResult>;

  void transmit(Pending& p, Micros now);
  // Starts queued requests on `ch` until one stays outstanding or the queue is empty.
  void advance(Channel& ch, Micros now, std::vector<Completion>& done);
  void complete(Pending& p, RequestOutcome outcome, Micros now, std::optional<MessageKey> by,
                std::vector<Completion>& done);
  static void fire(std::vector<Completion>& done);

  FrameSender& sender_;
  std::map<uint16_t, Channel> channels_;
  RequestId next_id_ = 1;
  RequestEngineStats stats_;
};

}  // namespace fleetgw::node
