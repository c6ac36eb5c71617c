#include "gateway/domain/alarm_payload.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <utility>

#include "fleetgw/v1/alarm.pb.h"
#include "gateway/domain/wire_numbers.h"

namespace fleetgw::domain {
namespace {

using wire::u32;

constexpr std::array<std::pair<std::string_view, v1::AlarmKind>, 7> kKinds = {{
    {"unauthorised_movement", v1::ALARM_KIND_UNAUTHORISED_MOVEMENT},
    {"lock_forced", v1::ALARM_KIND_LOCK_FORCED},
    {"lock_tamper", v1::ALARM_KIND_LOCK_TAMPER},
    {"low_battery", v1::ALARM_KIND_LOW_BATTERY},
    {"battery_removed", v1::ALARM_KIND_BATTERY_REMOVED},
    {"battery_swapped", v1::ALARM_KIND_BATTERY_SWAPPED},
    {"outside_operating_area", v1::ALARM_KIND_OUTSIDE_OPERATING_AREA},
}};

}  // namespace

int alarm_kind_number(std::string_view kind) {
  for (const auto& [name, number] : kKinds) {
    if (name == kind) return static_cast<int>(number);
  }
  return static_cast<int>(v1::ALARM_KIND_UNSPECIFIED);
}

storage::Bytes alarm_payload(const storage::AlarmRow& rec, const AlarmExtras& extras) {
  v1::Alarm a;
  for (const auto& [name, kind] : kKinds) {
    if (name == rec.kind) a.set_kind(kind);
  }
  a.set_transition(rec.transition == storage::AlarmTransition::kRaised
                       ? v1::ALARM_TRANSITION_RAISED
                       : v1::ALARM_TRANSITION_CLEARED);
  a.set_at_us(rec.ts_us);
  a.set_first_evidence_us(rec.first_evidence_us);
  if (rec.speed_kmh) a.set_speed_dkmh(u32(*rec.speed_kmh * 10));
  if (rec.max_speed_kmh) a.set_max_speed_dkmh(u32(*rec.max_speed_kmh * 10));
  if (rec.motor_rpm) a.set_motor_rpm(u32(*rec.motor_rpm));
  a.set_lock_kind(extras.lock_kind);
  if (rec.lock_node) a.set_lock_node(u32(*rec.lock_node));
  if (rec.lock_fault_bits) a.set_lock_fault_bits(static_cast<uint32_t>(*rec.lock_fault_bits));
  if (rec.soc_pct) a.set_soc_pct(u32(*rec.soc_pct));
  if (rec.threshold_pct) a.set_threshold_pct(u32(*rec.threshold_pct));
  a.set_old_bms_serial(rec.old_bms_serial);
  a.set_new_bms_serial(rec.new_bms_serial);
  if (extras.soh_pct) a.set_soh_pct(u32(*extras.soh_pct));
  if (extras.cycles) a.set_cycles(u32(*extras.cycles));
  a.set_detail(rec.detail);
  storage::Bytes out(a.ByteSizeLong());
  a.SerializeToArray(out.data(), static_cast<int>(out.size()));
  return out;
}

}  // namespace fleetgw::domain
