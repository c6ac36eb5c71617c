#include "gateway/node/iot_node.h"

#include <algorithm>
#include <utility>

#include "gateway/node/messages.h"

namespace fleetgw::node {
namespace {

NodeConfig validated(NodeConfig config) {
  config.validate();
  return config;
}

}  // namespace

IotNode::IotNode(NodeConfig config, const motinova::DecodeOptions& options, FrameSender& sender,
                 NodeHooks hooks)
    : config_(validated(std::move(config))),
      hooks_(std::move(hooks)),
      engine_(sender),
      registry_(RegistryConfig{config_.offline_timeout, config_.fault_stale_timeout}),
      poller_(config_.effective_poll_table(), config_.requests, engine_),
      broadcaster_(config_.identity, config_.broadcasts, options, sender),
      locks_(config_.fitted_locks, config_.locks, config_.requests,
             config_.broadcasts.event_transmissions, engine_),
      shutdown_(config_.shutdown, broadcaster_, engine_),
      rearm_(poller_) {
  registry_.add_observer(rearm_);
}

IotNode::~IotNode() {
  registry_.remove_observer(rearm_);
}

void IotNode::start(Micros now) {
  broadcaster_.start(now);
  poller_.start(now);
}

void IotNode::on_frame(const motinova::AppFrame& frame, const motinova::DecodedMessage& msg,
                       Micros now) {
  registry_.on_frame(frame, msg, now);
  poller_.on_frame(frame, now);
  engine_.on_frame(frame, now);
  locks_.on_frame(frame, now);
  shutdown_.on_frame(frame, now);
  if (is_peer_shutdown(frame)) {
    const motinova::Node initiator = motinova::source_of(frame.can_id);
    if (hooks_.on_peer_shutdown) hooks_.on_peer_shutdown(initiator, now);
    broadcaster_.send_event(Event::kReady, now);
  }
}

void IotNode::tick(Micros now) {
  registry_.tick(now);
  engine_.tick(now);
  locks_.tick(now);
  shutdown_.tick(now);
  poller_.tick(now);
  broadcaster_.tick(now);
}

Micros IotNode::next_event() const {
  return std::min({registry_.next_event(), engine_.next_event(), locks_.next_event(),
                   shutdown_.next_event(), poller_.next_event(), broadcaster_.next_event()});
}

void IotNode::set_own_fault(uint32_t mask, bool active, Micros now) {
  broadcaster_.set_fault(mask, active, now);
}

void IotNode::set_own_faults(uint32_t word, Micros now) {
  broadcaster_.set_faults(word, now);
}

void IotNode::vehicle_lock(Micros now) {
  broadcaster_.send_event(Event::kLock, now);
}

void IotNode::vehicle_unlock(Micros now) {
  broadcaster_.send_event(Event::kUnlock, now);
}

LockStart IotNode::actuate_lock(int lock_index, LockTarget target, Micros now,
                                LockActuator::Callback on_done, std::optional<Micros> timeout) {
  return locks_.start(lock_index, target, now, std::move(on_done), timeout);
}

bool IotNode::start_shutdown(Micros now, ShutdownProcedure::AccOff acc_off) {
  return shutdown_.start(now, registry_.online(motinova::Node::kMc),
                         registry_.online(motinova::Node::kObc),
                         acc_off ? std::move(acc_off) : hooks_.acc_off);
}

bool IotNode::start_shutdown_observed(Micros now, ShutdownProcedure::AccOff observer) {
  return start_shutdown(
      now, [hook = hooks_.acc_off, observer = std::move(observer)](const ShutdownOutcome& outcome) {
        if (hook) hook(outcome);
        if (observer) observer(outcome);
      });
}

}  // namespace fleetgw::node
