// The MQTT 5 sessions of one ingest worker, all in its one thread, with every QoS 1
// acknowledgement held until the caller says the messages are committed (issue 25).
//
// Why libmosquitto and how the PUBACKs wait (docs/backend.md, "Exactly once"): Debian's client
// libraries have no manual-acknowledgement API. Paho C sends the PUBACK right after the message
// callback returned, whatever it returned (measured: a MQTTAsync callback returning 0 is
// re-invoked later, but its PUBACK is already out and a SIGKILLed worker never sees the
// message again); libmosquitto queues the PUBACK before its callback. But libmosquitto driven
// by the caller's own loop with mosquitto_threaded_set(true) never writes from inside a read:
// every packet it makes (PUBACK, PINGREQ, SUBSCRIBE) waits in the session's output queue until
// the caller runs mosquitto_loop_write. So a session may receive any number of messages (up to
// its MQTT 5 receive maximum) and none is acknowledged until this class writes that queue,
// which it does only when every message the session received is committed. The MQTT protocol
// stays the library's; only the moment of the socket write is ours.
//
// Contract:
//  * Session i (1-based) is client id "<client_id>-s<i>", clean start off, session expiry
//    o.session_expiry_s, receive maximum o.inflight, maximum packet size o.max_packet_bytes,
//    keep-alive 60 s, subscribed to $share/<group>/<prefix>/# at QoS 1 (session 1 alone asks for
//    retained messages, on a new subscription only).
//  * A session's output queue is written only while it holds no message: held(i) == 0, i.e.
//    no message was received since the last acknowledge() (or since its connection was lost).
//  * acknowledge(): the caller committed every message received so far; their PUBACKs go.
//  * A lost connection is retried (100 ms doubling to 500 ms) with a new library object: nothing
//    queued on the lost connection (PUBACKs of messages still in the batch) is ever written;
//    the broker delivers those messages again (DUP) on the new one: a redelivery, never a loss.
//    (The reconnect's TCP connect blocks the loop, as the first one does.)
//  * close(true): DISCONNECT every session (the broker keeps the sessions) after writing what
//    is queued; close(false): the sockets are closed without writing anything (nothing held is
//    acknowledged). close(true, forget = true): the DISCONNECT sets session expiry 0, so the
//    broker forgets the sessions (a leave's end, once drained() == size()).
//  * leave(): the permanent leave (docs/backend.md "Leaving for good"): every session
//    unsubscribes from the shared filter instead of subscribing (on every later connection
//    too) and goes on delivering what the broker still queued for it; drained() counts the
//    sessions whose queue a round trip showed empty (see probe in mqtt_sessions.cc).
//  * Not thread-safe: one thread drives it.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "backend/ingest/ingest_options.h"

namespace fleetgw::ingest {

// One message received: the session's index (0-based), topic and payload (valid during the
// call only).
using MessageSink = std::function<void(std::size_t, std::string_view, std::string_view)>;

class MqttSessions {
 public:
  MqttSessions(const IngestOptions& o, std::string client_id, MessageSink sink);
  ~MqttSessions();
  MqttSessions(const MqttSessions&) = delete;
  MqttSessions& operator=(const MqttSessions&) = delete;

  // Opens every session's connection (TCP and TLS, blocking). False with `error` set when the
  // broker cannot be reached or its URI is not understood.
  bool connect(std::string& error);

  // One turn: waits up to `timeout` for the sessions' sockets and the `extra` descriptors; when
  // `reading`, reads messages from sessions not sealed into the sink while `want_more()` is
  // true; writes the queues of sessions that hold nothing; keep-alive and reconnects. Returns
  // a bit per readable extra descriptor (bit i: extra[i]).
  unsigned poll(std::chrono::milliseconds timeout, std::span<const int> extra, bool reading,
                const std::function<bool()>& want_more);

  // Seals the sessions holding messages received since the last seal as `generation` (> 0):
  // they are not read again until acknowledge(generation), so their queues hold the PUBACKs of
  // that generation's messages only. Returns how many sessions it sealed.
  std::size_t seal(std::uint64_t generation);
  // The messages of `generation` are committed: write those sessions' PUBACKs, read them again.
  // A session whose connection was lost meanwhile is no longer of the generation (its PUBACKs
  // died with the connection).
  void acknowledge(std::uint64_t generation);
  // Every message received so far is committed: write every session's PUBACKs.
  void acknowledge();
  void close(bool committed, bool forget = false);
  // Leaving the group for good: unsubscribe, drain, then close(true, true) (see Contract).
  void leave();
  std::size_t drained() const;  // leaving sessions whose queue the broker showed empty

  std::size_t size() const;
  std::size_t subscribed() const;  // sessions whose subscription the broker confirmed
  std::size_t connected() const;
  std::size_t resumed() const;  // sessions the broker still had at their first connection
  std::size_t held() const;     // messages received, not yet acknowledged
  // No session can deliver more before an acknowledgement: each is sealed or holds its
  // receive maximum.
  bool saturated() const;
  // A session refused by the broker (bad credentials, not authorised): the reason, else "".
  std::string refused() const;

  struct Session;

 private:
  bool open(Session& s, std::string& error);

  const IngestOptions& o_;
  std::string client_id_;
  MessageSink sink_;
  std::vector<std::unique_ptr<Session>> sessions_;
  bool closing_ = false;
};

}  // namespace fleetgw::ingest
