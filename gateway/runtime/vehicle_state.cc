#include "gateway/runtime/vehicle_state.h"

#include <cmath>
#include <cstdint>

#include "fleetgw/v1/state.pb.h"
#include "gateway/domain/alarm_payload.h"
#include "gateway/domain/payloads.h"

namespace fleetgw::runtime {
namespace {

// Rounded to nearest and clamped to the field: a hostile or broken reading cannot wrap.
uint32_t state_u32(double v) {
  if (!(v > 0)) return 0;
  return v >= 4294967295.0 ? UINT32_MAX : static_cast<uint32_t>(std::llround(v));
}

int32_t state_s32(double v) {
  if (std::isnan(v)) return 0;
  if (v <= -2147483648.0) return INT32_MIN;
  return v >= 2147483647.0 ? INT32_MAX : static_cast<int32_t>(std::llround(v));
}

void set_state_position(v1::Position& out, const gnss::Fix& p) {
  out.set_lat_e7(state_s32(p.lat_deg * 1e7));
  out.set_lon_e7(state_s32(p.lon_deg * 1e7));
  if (p.alt_m) out.set_alt_dm(state_s32(*p.alt_m * 10.0));
  if (p.hdop) out.set_hdop_centi(state_u32(*p.hdop * 100.0));
  if (p.horizontal_error_m) out.set_horizontal_error_dm(state_u32(*p.horizontal_error_m * 10.0));
  if (p.heading_deg) out.set_heading_ddeg(state_u32(*p.heading_deg * 10.0) % 3600);
  if (p.satellites > 0) out.set_satellites(static_cast<uint32_t>(p.satellites));
  out.set_fixed_at_us(p.fixed_at.count());
}

}  // namespace

std::string build_vehicle_state(const VehicleStateInputs& in, bool with_time) {
  v1::VehicleState s;
  if (with_time) s.set_updated_at_us(in.now.count());
  if (in.parked) s.set_mode(*in.parked ? v1::VEHICLE_MODE_PARKED : v1::VEHICLE_MODE_RIDING);
  s.set_bus_state(in.bus_state);
  if (const LiveState* live = in.live) {
    for (std::size_t i = 0; i < live->locks.size(); ++i) {
      const LockView& l = live->locks[i];
      if (l.kind.empty() || l.state_raw < 0) continue;  // not fitted, or never heard
      auto* out = s.add_locks();
      out->set_node("lock" + std::to_string(i + 1));
      out->set_kind(l.kind);
      out->set_state(static_cast<v1::LockState>(domain::lock_state_number(l.state_raw)));
      out->set_state_name(l.state);
    }
    if (live->speed_limit_kmh) s.set_speed_limit_dkmh(state_u32(*live->speed_limit_kmh * 10));
    if (live->assist_raw) s.set_assist(state_u32(static_cast<double>(*live->assist_raw)));
    if (live->assist) s.set_assist_name(*live->assist);
    if (live->soc_pct) s.set_soc_pct(state_u32(*live->soc_pct));
    if (live->range_km) s.set_range_m(state_u32(*live->range_km * 1000));
    if (live->odo_km && *live->odo_km >= 0) {
      s.set_odo_m(static_cast<uint64_t>(std::llround(*live->odo_km * 1000)));
    }
    for (const ActiveFault& f : live->faults) {
      auto* out = s.add_faults();
      out->set_node(f.node);
      out->set_name(f.name);
      if (f.code >= 0) out->set_code(static_cast<uint32_t>(f.code));
      out->set_severity(f.severity);
    }
  }
  for (const std::string_view kind : in.active_alarms) {
    s.add_active_alarms(static_cast<v1::AlarmKind>(domain::alarm_kind_number(kind)));
  }
  if (in.outside_operating_area) s.add_active_alarms(v1::ALARM_KIND_OUTSIDE_OPERATING_AREA);
  if (in.position) set_state_position(*s.mutable_position(), *in.position);
  return s.SerializeAsString();
}

std::optional<gnss::Fix> StatePositionFilter::comparable(
    const std::optional<gnss::Fix>& current) const {
  if (current && anchor_ && gnss::distance_m(*current, *anchor_) < min_move_m_) return anchor_;
  return current;
}

std::optional<StateThrottle::Clock::time_point> StateThrottle::deadline() const {
  if (!touched_) return std::nullopt;
  if (!last_sent_) return Clock::time_point::min();
  return *last_sent_ + min_interval_;
}

bool StateThrottle::offer(const std::string& comparable, Clock::time_point now) {
  touched_ = false;
  if (last_sent_ && comparable == last_) return false;
  last_ = comparable;
  last_sent_ = now;
  return true;
}

}  // namespace fleetgw::runtime
