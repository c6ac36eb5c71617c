#include "gateway/geofence/zone_payload.h"

#include "fleetgw/v1/zones.pb.h"
#include "gateway/domain/wire_numbers.h"

namespace fleetgw::geofence {

v1::ZoneEvent zone_event_message(const ZoneEvent& event) {
  using domain::wire::s32;
  using domain::wire::u32;
  v1::ZoneEvent m;
  m.set_zone_id(event.zone_id);
  m.set_zone_name(event.zone_name);
  m.set_kind(static_cast<v1::ZoneKind>(event.kind));  // the same numbers (zone_engine.h)
  m.set_transition(static_cast<v1::ZoneTransition>(event.transition));
  m.set_at_us(event.at.count());
  if (event.position) {
    const auto& p = *event.position;
    auto* out = m.mutable_position();
    out->set_lat_e7(s32(p.lat_deg * 1e7));
    out->set_lon_e7(s32(p.lon_deg * 1e7));
    if (p.alt_m) out->set_alt_dm(s32(*p.alt_m * 10.0));
    if (p.hdop) out->set_hdop_centi(u32(*p.hdop * 100.0));
    if (p.horizontal_error_m) out->set_horizontal_error_dm(u32(*p.horizontal_error_m * 10.0));
    if (p.heading_deg) out->set_heading_ddeg(u32(*p.heading_deg * 10.0) % 3600);
    if (p.satellites > 0) out->set_satellites(static_cast<std::uint32_t>(p.satellites));
    out->set_fixed_at_us(p.fixed_at.count());
  }
  m.set_bundle_version(event.bundle_version);
  if (event.speed_limit_kmh > 0)
    m.set_speed_limit_kmh(static_cast<std::uint32_t>(event.speed_limit_kmh));
  return m;
}

std::string zone_event_payload(const ZoneEvent& event) {
  return zone_event_message(event).SerializeAsString();
}

}  // namespace fleetgw::geofence
