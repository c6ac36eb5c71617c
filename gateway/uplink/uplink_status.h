// The uplink's part of a fleetgw.v1.Status: what its stats know about the connection and the
// publishes (docs/uplink.md, "Status").
//
// Contract: fill_status() sets last_publish_ok_at_us, the connect failure (last_connect_error,
// last_connect_error_at_us, tls_failures) and the MQTT 5 refusals (publish_refusals,
// last_publish_refusal, last_publish_refusal_code, last_publish_refusal_at_us) from `stats`, and
// leaves every other field alone. The uplink itself never calls it: the owner's status builder
// does (runtime/status_provider.h), and a test that drives an uplink alone plays that owner.
#pragma once

#include "fleetgw/v1/status.pb.h"
#include "gateway/uplink/uplink.h"

namespace fleetgw::uplink {

void fill_status(fleetgw::v1::Status& status, const UplinkStats& stats);

}  // namespace fleetgw::uplink
