// Zone events on the wire: the engine's ZoneEvent as a serialized fleetgw.v1.ZoneEvent, the
// payload the runtime stores in the outbox and publishes as Envelope.zone (field 21, topic
// .../zone). Pure: value in, bytes out.
//
// Contract: every field of the event is carried; the position as in telemetry (1e-7 degrees,
// decimetres, hundredths of HDOP, the receiver's fix time) and absent when the event has none
// (a zone removed with no fix known) -- never "at 0,0". Zone ids and names were validated when
// the bundle was accepted (zone_bundle.h), so they are valid UTF-8.
#pragma once

#include <string>

#include "gateway/geofence/zone_engine.h"

namespace fleetgw::v1 {
class ZoneEvent;
}  // namespace fleetgw::v1

namespace fleetgw::geofence {

v1::ZoneEvent zone_event_message(const ZoneEvent& event);
std::string zone_event_payload(const ZoneEvent& event);

}  // namespace fleetgw::geofence
