// Uplink publishing: draining the outbox in order within the in-flight window, telemetry
// batching (samples spliced as stored, envelope_writer.h), status messages, direct publishes,
// acking records once their publish completed, and holding the records of publishes an MQTT 5
// broker refused until their retry. See uplink.h for the contract.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/mqtt5.h"
#include "gateway/uplink/uplink_impl.h"

namespace fleetgw::uplink {

using std::chrono::duration_cast;

EnvelopeHeader Uplink::Impl::header(std::uint64_t seq, std::int64_t created_us) const {
  return EnvelopeHeader{config.vehicle_id, seq, created_us, config.firmware_version,
                        config.store_id};
}

std::string Uplink::Impl::serialize_status(Micros now, v1::OnlineState online,
                                           v1::ConnectionState conn) const {
  v1::Envelope env;
  fill_header(env, header(0, now.count()));
  auto* s = env.mutable_status();
  s->set_state(online);
  s->set_connection(conn);
  const OutboxStats os = outbox.stats();
  s->set_outbox_depth(os.depth);
  s->set_oldest_unsent_created_at_us(os.oldest_created_us);
  s->set_last_publish_ok_at_us(counters.last_publish_ok_us);
  s->set_bus_state(bus_state);
  s->set_firmware_version(config.firmware_version);
  s->set_connected_at_us(connect_started.count());
  s->set_publish_refusals(counters.publish_refusals);
  s->set_last_publish_refusal(counters.last_publish_refusal);
  s->set_last_publish_refusal_code(static_cast<std::uint32_t>(counters.last_publish_refusal_code));
  s->set_last_publish_refusal_at_us(counters.last_publish_refusal_us);
  if (status_decorator) status_decorator(*s);
  return env.SerializeAsString();
}

// The last will is registered at connect and published by the broker at some later moment of
// loss, so it carries only what stays true until then: no outbox, storage or attention figures,
// no creation time (the broker's receive time is the time of loss) and no store id (it is not a
// record).
std::string Uplink::Impl::serialize_will(Micros connecting_at) const {
  v1::Envelope env;
  fill_header(env, EnvelopeHeader{config.vehicle_id, 0, 0, config.firmware_version, {}});
  auto* s = env.mutable_status();
  s->set_state(v1::ONLINE_STATE_OFFLINE);
  s->set_connection(v1::CONNECTION_STATE_LOST);
  s->set_firmware_version(config.firmware_version);
  s->set_last_will(true);
  s->set_connected_at_us(connecting_at.count());
  return env.SerializeAsString();
}

void Uplink::Impl::publish_status(Micros now) {
  publish(topics.status,
          serialize_status(now, v1::ONLINE_STATE_ONLINE, v1::CONNECTION_STATE_CONNECTED),
          config.qos, true, {});
  last_status = now;
  status_changed = false;
}

// Safety net for the persistent session: Paho normally re-sends QoS 1 publishes interrupted by a
// connection loss and completes their tokens after the reconnect. If one is still open
// `resend_after` into a later connection, we stop waiting for it: its records become eligible
// again and go out in a new publish (a duplicate at worst, never a loss). A late completion of
// the old token is ignored because its id is gone.
void Uplink::Impl::resend_stale(Micros now) {
  if (now - connected_at < duration_cast<Micros>(config.resend_after)) return;
  for (auto it = in_flight.begin(); it != in_flight.end();) {
    if (it->second.connection != counters.connects) {
      spdlog::warn(
          "uplink: publish of {} record(s) from an earlier connection never completed; "
          "sending them again",
          it->second.seqs.size());
      release(it->second.seqs);
      it = in_flight.erase(it);
    } else {
      ++it;
    }
  }
}

void Uplink::Impl::release(const std::vector<std::uint64_t>& seqs) {
  for (const auto s : seqs) claimed.erase(s);
}

bool Uplink::Impl::publish(const std::string& topic, std::string payload, int qos, bool retained,
                           std::vector<std::uint64_t> seqs) {
  const std::uint64_t id = ++publish_id;
  const std::size_t bytes = payload.size();
  const std::size_t records = seqs.size();
  for (const auto s : seqs) claimed.insert(s);
  in_flight.emplace(id, InFlightEntry{std::move(seqs), qos, counters.connects, &topic});
  try {
    client->publish(make_message(topic, std::move(payload), qos, retained), detail::to_context(id),
                    publish_listener);
  } catch (const mqtt::exception& e) {
    // Rejected before it left (e.g. the connection just dropped): nothing was sent, so the
    // records simply stay in the outbox.
    ++counters.failed_publishes;
    release(in_flight[id].seqs);
    in_flight.erase(id);
    spdlog::warn("uplink: publish to {} refused by the client: {}", topic, e.what());
    return false;
  }
  ++counters.published_messages;
  counters.published_records += records;
  counters.bytes_published += bytes;
  counters.in_flight_high_water = std::max(counters.in_flight_high_water, in_flight.size());
  return true;
}

bool Uplink::Impl::publish_direct(std::string_view kind, std::string payload, Micros now) {
  if (state != UplinkState::kConnected) return false;
  const KindRoute* route = find_route(kind);
  if (route == nullptr) {
    spdlog::error("uplink: cannot publish a record of unknown kind '{}'", kind);
    return false;
  }
  std::optional<std::string> envelope;
  if (kind == kind::kTelemetry) {
    TelemetryBatchWriter writer;
    if (writer.add(payload, 0)) envelope = writer.take_envelope(header(0, now.count()));
  } else {
    envelope = serialize_record(*route, header(0, now.count()), payload);
  }
  if (!envelope) {
    spdlog::error("uplink: direct {} record ({} bytes) does not decode; not published", kind,
                  payload.size());
    return false;
  }
  // Outside the window: a direct record is rare and urgent (an answer nobody could store).
  return publish(topics.*(route->topic), std::move(*envelope), 1, false, {});
}

mqtt::message_ptr Uplink::Impl::make_message(const std::string& topic, std::string payload, int qos,
                                             bool retained) const {
  auto msg = mqtt::make_message(topic, std::move(payload), qos, retained);
  if (!envelope_props.empty()) msg->set_properties(envelope_props);
  return msg;
}

void Uplink::Impl::on_publish_done(Micros now, const detail::PublishDone& d) {
  const auto it = in_flight.find(d.id);
  if (it == in_flight.end()) return;  // given up on earlier (QoS 0 across a connection loss)
  auto seqs = std::move(it->second.seqs);
  const std::string* topic = it->second.topic;
  in_flight.erase(it);
  if (d.ok) {
    ++counters.acked_messages;
    counters.last_publish_ok_us = now.count();
    if (!seqs.empty()) {
      outbox.ack(seqs);
      counters.acked_records += seqs.size();
      if (!refused_seqs.empty()) {
        bool was_refused = false;
        for (const auto s : seqs) was_refused |= refused_seqs.erase(s) > 0;
        if (was_refused) on_refusal_cleared();
      }
    }
  } else if (const int reason = is_refusal(d.reason) ? d.reason : d.rc;
             config.protocol == MqttProtocol::kV5 && is_refusal(reason)) {
    // Paho's own failures are negative; a positive code >= 0x80 is the broker's answer.
    on_refused(now, topic != nullptr ? *topic : topics.base, std::move(seqs), reason);
    return;  // the records stay claimed until their retry
  } else {
    ++counters.failed_publishes;
    spdlog::warn("uplink: publish of {} record(s) failed ({}); they stay in the outbox",
                 seqs.size(), d.message);
  }
  release(seqs);
}

// The broker answered "no" (MQTT 5 PUBACK reason code >= 0x80): the records were not delivered
// and stay in the outbox. They stay claimed, and the drain takes nothing new, until the retry
// time; the wait doubles while refusals go on (refusal_backoff), so a broker that keeps refusing
// sees one window of publishes per back-off period, never a hot loop.
void Uplink::Impl::on_refused(Micros now, const std::string& topic, std::vector<std::uint64_t> seqs,
                              int reason) {
  ++counters.publish_refusals;
  ++counters.failed_publishes;
  const std::string why = reason_text(reason) + " (" + topic + ")";
  // A new reason goes into the retained status at the next poll; not when the status itself was
  // refused (it would be refused again, in a loop).
  if (why != counters.last_publish_refusal && topic != topics.status) status_changed = true;
  counters.last_publish_refusal = why;
  counters.last_publish_refusal_code = reason;
  counters.last_publish_refusal_us = now.count();
  if (!seqs.empty() && refusal_retry_at.count() == 0) {
    refusal_retry_at = now + duration_cast<Micros>(refusal_backoff.next());
  }
  if (logged_refusals.insert(why).second) {
    spdlog::warn(
        "uplink: the broker refused a publish: {}; {} record(s) stay in the outbox, retried "
        "with back-off (next in {} ms)",
        why, seqs.size(),
        refusal_retry_at.count() != 0 ? (refusal_retry_at - now).count() / 1000 : 0);
  }
  for (const auto s : seqs) refused_seqs.insert(s);
  refused_held.insert(refused_held.end(), seqs.begin(), seqs.end());
}

// A record the broker had refused got through: the cause is gone (e.g. the ACL was fixed).
void Uplink::Impl::on_refusal_cleared() {
  spdlog::info("uplink: the broker accepts the publishes it refused before ({})",
               counters.last_publish_refusal);
  refusal_backoff.reset();
  logged_refusals.clear();  // a later refusal is news again
  counters.last_publish_refusal.clear();
  counters.last_publish_refusal_code = 0;
  counters.last_publish_refusal_us = 0;
  status_changed = true;
}

// The back-off after a refusal passed: the held records become eligible again (they go first,
// in outbox order) and the drain resumes.
void Uplink::Impl::retry_refused(Micros) {
  refusal_retry_at = Micros{0};
  release(refused_held);
  refused_held.clear();
}

// The client was replaced or stopped: nothing is claimed any more.
void Uplink::Impl::forget_refused() {
  refusal_retry_at = Micros{0};
  refused_held.clear();
}

void Uplink::Impl::reject(const OutgoingRecord& e, std::string_view why) {
  spdlog::error("uplink: dropping outbox record seq {} kind '{}' ({} bytes): {}", e.seq, e.kind,
                e.payload.size(), why);
  ++counters.rejected_records;
  const std::uint64_t seq = e.seq;
  outbox.ack(std::span<const std::uint64_t>(&seq, 1));
}

std::size_t Uplink::Impl::capacity() const {
  return in_flight.size() >= config.max_in_flight ? 0 : config.max_in_flight - in_flight.size();
}

void Uplink::Impl::flush_batch(Micros now) {
  if (batch.empty()) return;
  std::string envelope =
      batch.writer.take_envelope(header(batch.seqs.front(), batch.first_created_us));
  const bool live =
      batch.newest_created_us >= now.count() - config.live_telemetry_max_age.count() * 1000;
  const int qos = live ? config.live_telemetry_qos : config.qos;
  auto seqs = std::move(batch.seqs);
  batch = PendingBatch{};
  // The records were claimed while batching; publish() claims them again (a no-op) and
  // releases them if the client refuses.
  publish(topics.telemetry, std::move(envelope), qos, false, std::move(seqs));
}

bool Uplink::Impl::batch_due(Micros now) const {
  return !batch.empty() &&
         (draining || batch.oldest_created_us + batch_delay.count() * 1000 <= now.count());
}

// Adds a telemetry record to the batch; false if the window is full and it was not taken.
bool Uplink::Impl::add_telemetry(Micros now, const OutgoingRecord& e) {
  const auto sample = TelemetryBatchWriter::prepare(e.payload, e.seq);
  if (!sample) {
    reject(e, "payload is not a fleetgw.v1.TelemetrySample");
    return true;
  }
  const std::size_t size = sample->accounted_size();
  if (!batch.empty() && (batch.seqs.size() >= config.telemetry_batch_max_samples ||
                         batch.bytes + size > config.telemetry_batch_max_bytes)) {
    if (capacity() == 0) return false;
    flush_batch(now);
  }
  if (batch.empty()) {
    batch.first_created_us = e.created_us;
    batch.oldest_created_us = e.created_us;
    batch.newest_created_us = e.created_us;
  }
  batch.oldest_created_us = std::min(batch.oldest_created_us, e.created_us);
  batch.newest_created_us = std::max(batch.newest_created_us, e.created_us);
  batch.writer.add(*sample);
  batch.seqs.push_back(e.seq);
  batch.bytes += size;
  claimed.insert(e.seq);
  if (batch.seqs.size() >= config.telemetry_batch_max_samples) {
    if (capacity() == 0) return true;  // stays pending; flushed when the window opens
    flush_batch(now);
  }
  return true;
}

bool Uplink::Impl::publish_record(const OutgoingRecord& e) {
  const KindRoute* route = find_route(e.kind);
  if (route == nullptr || e.kind == kind::kTelemetry) {
    reject(e, "unknown record kind");
    return true;
  }
  auto envelope = serialize_record(*route, header(e.seq, e.created_us), e.payload);
  if (!envelope) {
    reject(e, "payload does not decode as the kind's message");
    return true;
  }
  return publish(topics.*(route->topic), std::move(*envelope), config.qos, false, {e.seq});
}

void Uplink::Impl::drain(Micros now) {
  if (state != UplinkState::kConnected) return;
  if (refusal_retry_at.count() != 0) return;  // the broker refused records: wait for the retry
  // A full batch left pending because the window was closed goes first.
  if (!batch.empty() && capacity() > 0 &&
      (batch.seqs.size() >= config.telemetry_batch_max_samples || batch_due(now))) {
    flush_batch(now);
  }
  bool more = true;
  while (more && capacity() > 0 && state == UplinkState::kConnected) {
    // One publish per free slot for ordinary records, but a whole batch per slot for telemetry:
    // fetch for telemetry only while the queue head is telemetry, so a backlog of single
    // records does not copy thousands of entries per poll.
    const std::size_t want = std::min<std::size_t>(
        head_is_telemetry ? capacity() * config.telemetry_batch_max_samples : capacity(), 4096);
    const auto entries = outbox.peek(want, config.max_fetch_bytes, claimed);
    more = entries.size() == want;
    if (entries.empty()) break;
    head_is_telemetry = entries.back().kind == kind::kTelemetry;
    for (const auto& e : entries) {
      if (claimed.contains(e.seq)) continue;  // defensive: a source ignoring `exclude`
      const bool taken = e.kind == kind::kTelemetry ? add_telemetry(now, e)
                                                    : (capacity() > 0 && publish_record(e));
      if (!taken) {
        more = false;
        break;
      }
    }
  }
  if (batch_due(now) && capacity() > 0) flush_batch(now);
}

}  // namespace fleetgw::uplink
