#include "gateway/node/shutdown.h"

#include <utility>

#include "gateway/node/messages.h"

namespace fleetgw::node {

bool is_mc_ready(const motinova::AppFrame& frame) {
  return frame.can_id == ids::kMcBroadcast && frame.function == fn::kMcReady &&
         is_keyword(frame, keyword::kReady);
}

bool is_obc_ready(const motinova::AppFrame& frame) {
  return frame.can_id == ids::kObcBroadcast && frame.function == fn::kObcReady &&
         is_keyword(frame, keyword::kReady);
}

bool is_peer_shutdown(const motinova::AppFrame& frame) {
  const bool obc = frame.can_id == ids::kObcBroadcast && frame.function == fn::kObcShutdown;
  const bool bms = frame.can_id == ids::kBmsBroadcast && frame.function == fn::kBmsShutdown;
  return (obc || bms) && is_keyword(frame, keyword::kShutdown);
}

ShutdownProcedure::ShutdownProcedure(ShutdownPolicy policy, OwnBroadcaster& broadcaster,
                                     RequestEngine& engine)
    : policy_(policy), broadcaster_(broadcaster), engine_(engine) {}

bool ShutdownProcedure::start(Micros now, bool await_mc, bool await_obc, AccOff acc_off) {
  if (running_) return false;
  running_ = true;
  started_ = now;
  outcome_ = ShutdownOutcome{};
  outcome_.awaited_mc = await_mc;
  outcome_.awaited_obc = await_obc;
  acc_off_ = std::move(acc_off);
  broadcaster_.send_event(Event::kShutdown, now);
  if (policy_.order_obc_off) {
    // Through the engine so it never overlaps a read in flight on 0x763 (no answer expected).
    Request req;
    req.frame = keyword_frame(ids::kIotToObc, motinova::Mode::kWrite, fn::kObcOrderShutdown,
                              keyword::kShutdown);
    engine_.submit(std::move(req), nullptr, now);
  }
  if (!await_mc && !await_obc) finish(false, now);
  return true;
}

void ShutdownProcedure::on_frame(const motinova::AppFrame& frame, Micros now) {
  if (!running_) return;
  if (is_mc_ready(frame)) outcome_.mc_ready = true;
  if (is_obc_ready(frame)) outcome_.obc_ready = true;
  const bool all =
      (!outcome_.awaited_mc || outcome_.mc_ready) && (!outcome_.awaited_obc || outcome_.obc_ready);
  if (all) finish(false, now);
}

void ShutdownProcedure::tick(Micros now) {
  if (running_ && now - started_ >= policy_.ready_timeout) finish(true, now);
}

void ShutdownProcedure::finish(bool timed_out, Micros now) {
  running_ = false;
  outcome_.timed_out = timed_out;
  outcome_.elapsed = now - started_;
  // Everyone awaited has answered (or we give up): further SHUTDOWN repeats would only make
  // nodes that already saved their state do it again. With nobody to wait for, the repeats run
  // their course for whoever else listens (the BMS).
  if (outcome_.awaited_mc || outcome_.awaited_obc) broadcaster_.stop_event(Event::kShutdown);
  AccOff hook = std::move(acc_off_);
  acc_off_ = nullptr;
  if (hook) hook(outcome_);
}

}  // namespace fleetgw::node
