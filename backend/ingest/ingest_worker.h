// `fleetgw ingest`: a reference backend consumer. Subscribes with an MQTT 5 shared subscription
// ($share/<group>/<prefix>/#, QoS 1, persistent session) and writes every decoded message into
// PostgreSQL through IngestStore, acknowledging a message to the broker only after its
// transaction committed.
//
// How the acknowledgement waits for the commit (docs/backend.md, "Exactly once"): Paho C 1.3.12
// has no manual-acknowledgement API, but it calls the message callback on its receive thread
// BEFORE it sends the PUBACK of a QoS 1 message (verified against mosquitto: a worker killed
// inside the callback gets the message again, DUP set, on its next connection). The callback
// therefore decodes, writes and commits, and only then returns; a process killed at any point
// before the return leaves the message unacknowledged in its session on the broker. The price:
// one transaction per MQTT message (a telemetry message carries up to 200 samples).
//
// Contract:
//  * run_ingest() returns the process exit status: 0 after SIGINT/SIGTERM or `duration_s`,
//    1 when PostgreSQL or the broker cannot be reached at start (named on stderr), 2 for bad
//    options; with `gaps` it prints the gap report (one line per hole) and returns 0 when it is
//    empty, 1 otherwise.
//  * A malformed message (decode_message() Reject, or data the server refuses) is acknowledged
//    (it would come back for ever otherwise), stored in rejected_messages, counted by reason,
//    and logged once per reason with its topic (later ones at debug level).
//  * PostgreSQL unavailable while a message is in hand: retried with back-off (100 ms .. 5 s),
//    the message stays unacknowledged; a stop request during that wait exits (status 3) without
//    acknowledging it: the broker delivers it again.
//  * On exit one summary line: messages, records, rows inserted, duplicates, rejects by reason.
#pragma once

#include "gateway/ingest/ingest_options.h"

namespace fleetgw::ingest {

int run_ingest(const IngestOptions& options);

}  // namespace fleetgw::ingest
