// The health part of the published fleetgw.v1.Status, from the same typed facts the status
// document and `fleetgw status` are judged by (status_health.h), so the fleet back end and the
// technician see the same verdict from one set of rules.
//
// Contract: fill_status() sets Status.storage (when `health` has a storage section),
// attention_needed and one `attention` line per finding of evaluate(health, rules), and leaves
// every other field alone (the connection's and the uplink's fields are filled elsewhere:
// runtime/status_provider.h, uplink/uplink_status.h). Nothing is read from a JSON document.
#pragma once

#include "fleetgw/v1/status.pb.h"
#include "gateway/status/status_health.h"
#include "gateway/status/status_report.h"

namespace fleetgw::status {

void fill_status(fleetgw::v1::Status& status, const Health& health,
                 const AttentionRules& rules = {});

}  // namespace fleetgw::status
