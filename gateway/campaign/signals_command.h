// `fleetgw signals [--json]`: the signal catalogue (motinova/signal_catalogue.h) for people and
// for tools -- what a campaign may name (docs/campaigns.md).
//
// Contract: one row per signal in catalogue order: name, type, unit, the message (catalogue
// name, CAN ID, COMMAND) and its one-line title. The table form is common::write_table's; --json
// is one JSON array of objects {name, type, unit, node, message, can_id, command, title}, can_id
// and command as "0x720" / "0x1120" strings. Always exit 0.
#pragma once

#include <iosfwd>

namespace fleetgw::campaign {

int run_signals(bool json, std::ostream& out);

}  // namespace fleetgw::campaign
