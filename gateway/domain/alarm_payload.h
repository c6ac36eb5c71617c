// AlarmRecord -> fleetgw.v1.Alarm (the uplink payload of an alarm, proto/fleetgw/v1/alarm.proto).
//
// Contract: a pure function; units per the unit rule (speed in 0.1 km/h, whole percent,
// rounded to nearest, clamped to the field's range); absent values stay absent. An unknown
// `kind` text maps to ALARM_KIND_UNSPECIFIED.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "storage/records.h"

namespace fleetgw::domain {

// What the payload carries beyond the storage row.
struct AlarmExtras {
  std::string lock_kind;          // configured kind of the lock concerned
  std::optional<double> soh_pct;  // battery_swapped: the new pack's
  std::optional<double> cycles;   // battery_swapped: the new pack's
};

// The fleetgw.v1.AlarmKind number of a kind text (0, UNSPECIFIED, when unknown).
int alarm_kind_number(std::string_view kind);

storage::Bytes alarm_payload(const storage::AlarmRow& rec, const AlarmExtras& extras);

}  // namespace fleetgw::domain
