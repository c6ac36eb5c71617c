// Hand-built frames at chosen virtual times, for the cases the simulator cannot stage precisely
// (a flapping bit, a fault word that goes silent, lifetime counters that change).
#pragma once

#include <cstdint>
#include <string_view>

#include "gateway/domain/domain_trackers.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"

namespace fleetgw::domain::testing {

inline motinova::MessageWriter writer(uint16_t can_id, uint8_t function) {
  const motinova::MessageDesc* d = motinova::Catalogue::standard().find(can_id, function);
  if (d == nullptr) throw std::logic_error("no such message");
  return motinova::MessageWriter(*d, motinova::DecodeOptions{});
}

// Decodes `frame` and feeds it to the trackers at `now`, then ticks them.
inline void feed(DomainTrackers& t, const motinova::AppFrame& frame, motinova::Micros now) {
  static const motinova::DecodeOptions options{};  // the message points into it
  motinova::DecodedMessage msg;
  motinova::decode(frame, motinova::Catalogue::standard(), options, msg);
  t.on_message(msg, now);
  t.tick(now);
}

inline motinova::AppFrame mc_faults(uint32_t word) {
  return writer(0x710, 0x11).raw("raw", word).frame();
}

}  // namespace fleetgw::domain::testing
