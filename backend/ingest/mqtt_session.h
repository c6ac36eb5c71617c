// One MQTT 5 session of an ingest worker, run in a child process of its own (ingest_worker.h
// says why: Paho C serves every client of a process from ONE receive thread and sends a QoS 1
// PUBACK when the message callback returns, so one process can hold only one unacknowledged
// message; K session processes let one batch hold K messages).
//
// Contract (the frames on `fd`, a stream socket to the worker):
//  * session → worker: 'S' <u8 session_present> once subscribed (again after each reconnect);
//    'M' <u32 topic bytes> <u32 payload bytes> <topic> <payload> for each message received;
//    'D' after a stop request, once the session is disconnected from the broker.
//  * worker → session: one byte per 'M': 'A' = its rows are committed: the callback returns and
//    Paho sends the PUBACK; 'N' = not committed, only ever sent after 'D': the callback never
//    returns (Paho could still acknowledge on a connection not yet closed); the process ends
//    from its main thread and the broker keeps the message.
//  * The worker gone (EOF or an error on `fd`) while a message is in hand: the process ends
//    with _exit(4) inside the callback, never returning to Paho, so nothing is acknowledged
//    (the worker crashed; this is not the stop path).
//  * run_session() returns the exit status: 0 after SIGTERM/SIGINT (3 when it ended holding a
//    message the worker could not commit) (taken with sigwait: the
//    caller blocks them first) or the worker's death (PR_SET_PDEATHSIG), 1 when the broker
//    cannot be reached at start (named on stderr).
//  * After a message larger than 64 KiB the session returns freed memory to the system
//    (malloc_trim), so its resident memory comes back down (issue 24).
#pragma once

#include <cstdint>
#include <string>

#include "backend/ingest/ingest_options.h"

namespace fleetgw::ingest {

// `first_session`: this session alone asks for the retained messages (MQTT 5 retain handling
// "on a new subscription"); the others never get them.
int run_session(const IngestOptions& o, const std::string& client_id, bool first_session, int fd);

// Threshold above which a message's buffers are given back to the system once it is done.
constexpr std::size_t kLargeMessageBytes = 64 * 1024;

}  // namespace fleetgw::ingest
