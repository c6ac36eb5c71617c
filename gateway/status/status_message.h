// The health part of the published fleetgw.v1.Status, taken from the same status document
// `fleetgw status` shows (status_report.h), so the fleet back end and the technician see the same
// verdict from one set of rules.
//
// Contract: fill_status_health() sets Status.storage (when the document has a "storage"
// section), last_connect_error / last_connect_error_at_us / tls_failures (from "broker"),
// attention_needed and one `attention` line per finding of evaluate(document, rules). It leaves
// the other fields (state, connection, outbox, bus, firmware) alone and never throws on a
// malformed document (the findings then say "malformed").
#pragma once

#include <nlohmann/json.hpp>

#include "fleetgw/v1/status.pb.h"
#include "gateway/status/status_report.h"

namespace fleetgw::status {

void fill_status_health(fleetgw::v1::Status& status, const nlohmann::json& document,
                        const AttentionRules& rules = {});

}  // namespace fleetgw::status
