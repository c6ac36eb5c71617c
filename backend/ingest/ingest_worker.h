// `fleetgw ingest`: a reference backend consumer. Subscribes with an MQTT 5 shared subscription
// ($share/<group>/<prefix>/#, QoS 1, persistent sessions) and writes the decoded messages into
// PostgreSQL in batches (IngestStore::write_batch), acknowledging each message to the broker
// only after the transaction holding its rows committed.
//
// How the acknowledgements wait for a batch (docs/backend.md, "Exactly once"): the worker is
// ONE process holding K MQTT sessions of the group (--sessions, mqtt_sessions.h), each allowed
// --inflight unacknowledged messages by the broker (MQTT 5 receive maximum). The library queues
// each message's PUBACK without writing it. The loop thread reads and decodes into a batch
// (closed at --batch rows, 32 MiB, every session at its receive maximum, or --batch-delay-ms
// after its first message) and hands it to the database thread, sealing the sessions holding
// its messages: they are not read again until that batch committed, when their queues (the
// PUBACKs of exactly that batch) are written. Meanwhile the other sessions fill the next batch.
//
// Contract:
//  * run_ingest() returns the process exit status: 0 after SIGINT/SIGTERM or `duration_s` once
//    every message in hand is committed and acknowledged and every session disconnected (a
//    clean drain, no _exit), 3 when it stopped with messages it could not commit (PostgreSQL
//    down: not acknowledged, the broker delivers them again), 1 when PostgreSQL or the broker
//    cannot be reached at start or the broker refuses a session (named on stderr), 2 for bad
//    options; with `gaps` it prints the gap report (one line per hole) and returns 0 when it
//    is empty, 1 otherwise.
//  * Leaving the group for good (`leave`, or SIGUSR1 to a running worker; docs/backend.md
//    "Leaving for good"): the sessions unsubscribe, what the broker still queued for them is
//    committed and acknowledged as usual, and once a round trip shows every session's queue
//    empty they DISCONNECT with session expiry 0 (the broker forgets them) and it returns 0;
//    stopped before that (SIGTERM, a crash) the sessions stay, unsubscribed: a new leave
//    finishes the job (status 3 after a SIGTERM).
//  * A malformed message (decode_message() Reject) or one the database refuses is
//    acknowledged (it would come back for ever otherwise) once stored in rejected_messages in
//    the batch's transaction, counted by reason, and logged once per reason with its topic
//    (later ones at debug level); the rest of its batch commits.
//  * PostgreSQL unavailable: the batch is retried with back-off (100 ms .. 5 s) by the
//    database thread (no library callback sleeps), its messages stay unacknowledged; the next
//    batch fills and then nothing more is read, so at most two batches are in memory whatever
//    the backlog.
//  * Memory: one message's rows are bounded by decode_message (kMaxSamples, the broker's
//    packet limit); after a message over 64 KiB, freed memory is given back (malloc_trim).
//  * Test hook: FLEETGW_INGEST_CRASH_AT=before_copy (the batch's transaction open, no row sent)
//    |after_copy (every row written, before COMMIT)|after_commit (before any acknowledgement)
//    SIGKILLs the worker at that point of its FLEETGW_INGEST_CRASH_BATCH-th batch holding
//    records (default 1).
//  * On exit one summary line: messages, records, rows inserted, duplicate records ignored,
//    rejects by reason, out-of-order states ignored, batches.
#pragma once

#include "backend/ingest/ingest_options.h"

namespace fleetgw::ingest {

int run_ingest(const IngestOptions& options);

}  // namespace fleetgw::ingest
