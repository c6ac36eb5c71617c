// Small helpers shared by the trackers: timestamped readings with an age limit, recognising the
// keyword messages that drive rides and locks, and the names the trackers report.
//
// Contract: pure functions and value types; nothing here keeps state between calls.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "motinova/can.h"
#include "motinova/codec.h"

namespace fleetgw::domain {

using motinova::Micros;

// A value and when it was heard.
struct Reading {
  double value = 0;
  Micros at{0};
};

// The reading's value when it is at most max_age old at `now`.
inline std::optional<double> fresh(const std::optional<Reading>& r, Micros now, Micros max_age) {
  if (!r || now - r->at > max_age) return std::nullopt;
  return r->value;
}

// Stores msg.number(field) into `slot` (stamped `now`) when the field is present and valid.
inline void update(std::optional<Reading>& slot, const motinova::DecodedMessage& msg,
                   std::string_view field, Micros now) {
  if (const auto v = msg.number(field)) slot = Reading{*v, now};
}

// What a keyword or well-known message means to the trackers. Messages that merely share a name
// (the IOT's per-lock "lock" commands on 0x767.., the OBC-only SHUTDOWN on 0x763) are kOther.
enum class BusEvent : uint8_t {
  kOther,
  kVehicleLock,    // 0x760 LOCK: one-touch vehicle lock
  kVehicleUnlock,  // 0x760 UNLOCK
  kShutdown,       // system power-down: 0x760 (IOT), 0x730 (power key), 0x720 (BMS auto-off)
};
BusEvent classify(const motinova::DecodedMessage& msg);

// Assist-level name as configured (U7), or "0xNN" for an unnamed level.
std::string assist_name(const motinova::DecodedMessage& mc_status);

// "20240601T080012.345678Z": the ride id's time part (UTC, microseconds).
std::string utc_basic(Micros t);

}  // namespace fleetgw::domain
