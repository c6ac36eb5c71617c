// Clock helpers of the runtime: the wall clock in the microseconds every stage speaks, and
// milliseconds from configuration turned into that unit. One definition for the whole area.
#pragma once

#include <chrono>
#include <cstdint>

#include "motinova/can.h"

namespace fleetgw::runtime {

// Wall-clock time since the Unix epoch, microseconds.
inline motinova::Micros system_now() {
  return std::chrono::duration_cast<motinova::Micros>(
      std::chrono::system_clock::now().time_since_epoch());
}

// A configured number of milliseconds as Micros.
inline motinova::Micros ms(std::int64_t v) {
  return motinova::Micros(v * 1000);
}

}  // namespace fleetgw::runtime
