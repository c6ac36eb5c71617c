#include "gateway/node/own_broadcasts.h"

#include <algorithm>

#include "gateway/node/messages.h"

namespace fleetgw::node {

std::string_view event_name(Event e) {
  switch (e) {
    case Event::kReady:
      return "ready";
    case Event::kShutdown:
      return "shutdown";
    case Event::kLock:
      return "lock";
    case Event::kUnlock:
      return "unlock";
  }
  return "?";
}

OwnBroadcaster::OwnBroadcaster(const Identity& identity, BroadcastPolicy policy,
                               const motinova::DecodeOptions& options, FrameSender& sender)
    : policy_(policy),
      options_(options),
      sender_(sender),
      model_info_(model_info_frame(identity.model, identity.serial, identity.hardware,
                                   identity.firmware())) {}

motinova::AppFrame OwnBroadcaster::event_frame(Event e) {
  using motinova::Mode;
  switch (e) {
    case Event::kReady:
      return keyword_frame(ids::kIotBroadcast, Mode::kReport, fn::kIotReady, keyword::kReady);
    case Event::kShutdown:
      return keyword_frame(ids::kIotBroadcast, Mode::kReport, fn::kIotShutdown, keyword::kShutdown);
    case Event::kLock:
      return keyword_frame(ids::kIotBroadcast, Mode::kReport, fn::kIotLock, keyword::kLock);
    case Event::kUnlock:
      return keyword_frame(ids::kIotBroadcast, Mode::kReport, fn::kIotUnlock, keyword::kUnlock);
  }
  return {};
}

void OwnBroadcaster::start(Micros now) {
  started_ = true;
  transmit(model_info_);
  ++stats_.model_info;
  next_model_info_ = now + policy_.model_info_period;
  send_faults(now);
}

void OwnBroadcaster::tick(Micros now) {
  for (std::size_t i = 0; i < kEventKinds; ++i) {
    EventSchedule& ev = events_[i];
    if (ev.remaining > 0 && now >= ev.next) {
      transmit(event_frame(static_cast<Event>(i)));
      ++stats_.events[i];
      --ev.remaining;
      ev.next = now + policy_.event_interval;
    }
  }
  if (!started_) return;
  if (now >= next_model_info_) {
    transmit(model_info_);
    ++stats_.model_info;
    next_model_info_ = now + policy_.model_info_period;
  }
  if (now >= next_faults_) send_faults(now);
}

Micros OwnBroadcaster::next_event() const {
  Micros next = Micros::max();
  for (const EventSchedule& ev : events_) {
    if (ev.remaining > 0) next = std::min(next, ev.next);
  }
  if (started_) next = std::min({next, next_model_info_, next_faults_});
  return next;
}

void OwnBroadcaster::set_faults(uint32_t word, Micros now) {
  if (word == faults_) return;
  faults_ = word;
  if (started_) send_faults(now);  // on change: at once, and the period follows the new word
}

void OwnBroadcaster::set_fault(uint32_t mask, bool active, Micros now) {
  set_faults(active ? (faults_ | mask) : (faults_ & ~mask), now);
}

void OwnBroadcaster::send_event(Event e, Micros now) {
  if (e == Event::kLock) stop_event(Event::kUnlock);
  if (e == Event::kUnlock) stop_event(Event::kLock);
  EventSchedule& ev = events_[index(e)];
  // Events are sent at once even before start(): they answer someone (READY) or act on a user
  // command, and holding them back would only delay the reaction.
  transmit(event_frame(e));
  ++stats_.events[index(e)];
  ev.remaining = policy_.event_transmissions - 1;
  ev.next = now + policy_.event_interval;
}

void OwnBroadcaster::stop_event(Event e) {
  events_[index(e)].remaining = 0;
}

void OwnBroadcaster::send_faults(Micros now) {
  transmit(fault_word_frame(faults_, options_));
  ++stats_.fault_words;
  next_faults_ = now + (faults_ != 0 ? policy_.fault_period_faulty : policy_.fault_period_ok);
}

void OwnBroadcaster::transmit(const motinova::AppFrame& f) {
  if (!sender_.send(f)) ++stats_.send_failures;
}

}  // namespace fleetgw::node
