// Uplink publishing: draining the outbox in order within the in-flight window, telemetry
// batching (samples spliced as stored, envelope_writer.h), status messages, direct publishes,
// acking records once their publish completed, and holding the records of publishes an MQTT 5
// broker refused until their retry, one lane per kind (the other kinds keep flowing). See
// uplink.h for the contract.
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

// The owner's status (set_status), stamped with what only this connection knows.
std::string Uplink::Impl::serialize_status(Micros now, v1::OnlineState online,
                                           v1::ConnectionState conn) const {
  v1::Envelope env;
  fill_header(env, header(0, now.count()));
  v1::Status* s = env.mutable_status();
  *s = status;
  s->set_state(online);
  s->set_connection(conn);
  s->set_connected_at_us(connect_started.count());
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
  if (publish(topics.status,
              serialize_status(now, v1::ONLINE_STATE_ONLINE, v1::CONNECTION_STATE_CONNECTED),
              config.qos, true, {})) {
    status_due = false;
  }
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
    spdlog::error("uplink: direct {} record ({} bytes) is not well-formed; not published", kind,
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

namespace {

// The record kind of a publish: its topic's kTopicTable entry ("other" for a topic outside the
// table, which the uplink never publishes to).
std::string_view kind_of(const Topics& topics, const std::string* topic) {
  const TopicSpec* spec = topic != nullptr ? find_topic(topics, topic) : nullptr;
  if (spec == nullptr || spec->record_kind.empty()) return "other";
  return spec->record_kind;
}

}  // namespace

std::size_t Uplink::Impl::RefusedLanes::size() const {
  std::size_t n = 0;
  for (const auto& [kind, lane] : by_kind) n += lane.held.size();
  return n;
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
    }
    if (!refused_held.by_kind.empty()) on_accepted(kind_of(topics, topic));
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

// The broker answered "no" (MQTT 5 PUBACK reason code >= 0x80) to a publish of one kind: its
// records were not delivered and stay in the outbox, claimed until the lane's retry time; the
// kind's newer records are not drawn meanwhile, every other kind keeps flowing.
void Uplink::Impl::on_refused(Micros now, const std::string& topic, std::vector<std::uint64_t> seqs,
                              int reason) {
  ++counters.publish_refusals;
  ++counters.failed_publishes;
  const std::string_view kind = kind_of(topics, &topic);
  auto lane_it = refused_held.by_kind.find(kind);
  if (lane_it == refused_held.by_kind.end()) {
    lane_it = refused_held.by_kind.emplace(std::string(kind), RefusedLane(refusal_backoff)).first;
    refusal_backoff.next();  // the next lane's jitter differs from this one's
    refusal_backoff.reset();
  }
  RefusedLane& lane = lane_it->second;
  lane.why = reason_text(reason) + " (" + topic + ")";
  lane.code = reason;
  lane.at = now;
  if (!seqs.empty() && lane.retry_at.count() == 0) {
    lane.retry_at = now + duration_cast<Micros>(lane.backoff.next());
  }
  if (logged_refusals.insert(lane.why).second) {
    spdlog::warn(
        "uplink: the broker refused a publish: {}; {} record(s) stay in the outbox, retried "
        "with back-off (next in {} ms); other kinds keep flowing",
        lane.why, seqs.size(),
        lane.retry_at.count() != 0 ? (lane.retry_at - now).count() / 1000 : 0);
  }
  lane.held.insert(lane.held.end(), seqs.begin(), seqs.end());
  if (kind == kind::kTelemetry && !batch.empty()) {
    // Samples batched behind the refused ones would overtake them: back to the outbox.
    release(batch.seqs);
    batch = PendingBatch{};
  }
  refusals_changed(kind);
}

// The broker accepted a publish of `kind`: the cause of its refusals is gone (e.g. the ACL was
// fixed). Records it still holds go out at once.
void Uplink::Impl::on_accepted(std::string_view kind) {
  const auto it = refused_held.by_kind.find(kind);
  if (it == refused_held.by_kind.end()) return;
  spdlog::info("uplink: the broker accepts the {} publishes it refused before ({})", kind,
               it->second.why);
  release(it->second.held);
  logged_refusals.erase(it->second.why);  // a later refusal is news again
  refused_held.by_kind.erase(it);
  refusals_changed(kind);
}

// The refusals in force, one per kind, go into the counters (and so into every Status):
// last_publish_refusal names each refused kind's reason and topic, "; "-separated.
void Uplink::Impl::refusals_changed(std::string_view kind) {
  std::string text;
  const RefusedLane* latest = nullptr;
  refusal_retry_at = Micros{0};
  for (const auto& [k, lane] : refused_held.by_kind) {
    text += (text.empty() ? "" : "; ") + lane.why;
    if (latest == nullptr || lane.at > latest->at) latest = &lane;
    if (lane.retry_at.count() != 0 &&
        (refusal_retry_at.count() == 0 || lane.retry_at < refusal_retry_at)) {
      refusal_retry_at = lane.retry_at;
    }
  }
  // News for the retained status: the owner is asked for a fresh one; not when only the status
  // itself was refused (it would be refused again, in a loop).
  if (text != counters.last_publish_refusal && kind != kind::kStatus &&
      state == UplinkState::kConnected) {
    status_wanted = true;
  }
  counters.last_publish_refusal = std::move(text);
  counters.last_publish_refusal_code = latest != nullptr ? latest->code : 0;
  counters.last_publish_refusal_us = latest != nullptr ? latest->at.count() : 0;
}

// A lane's back-off passed: its held records become eligible again (they go first within their
// kind, in outbox order).
void Uplink::Impl::retry_refused(Micros now) {
  for (auto& [kind, lane] : refused_held.by_kind) {
    if (lane.retry_at.count() == 0 || lane.retry_at > now) continue;
    lane.retry_at = Micros{0};
    release(lane.held);
    lane.held.clear();
  }
  refusals_changed(kind::kStatus);  // only the retry time changed: no status news
}

// The client was replaced or stopped: nothing is claimed any more. The reasons stay (the broker
// still refuses until a publish of the kind is accepted), the records are simply drawn again.
void Uplink::Impl::forget_refused() {
  for (auto& [kind, lane] : refused_held.by_kind) {
    lane.retry_at = Micros{0};
    lane.held.clear();
  }
  refusal_retry_at = Micros{0};
}

// Kinds whose refused records wait for their retry: the drain leaves their newer records too.
KindSet Uplink::Impl::blocked_kinds() const {
  KindSet out;
  for (const auto& [kind, lane] : refused_held.by_kind) {
    if (lane.retry_at.count() != 0) out.insert(kind);
  }
  return out;
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
    reject(e, "payload is not well-formed protobuf wire format");
    return true;
  }
  return publish(topics.*(route->topic), std::move(*envelope), config.qos, false, {e.seq});
}

void Uplink::Impl::drain(Micros now) {
  if (state != UplinkState::kConnected) return;
  // Kinds the broker refused wait for their lane's retry; the others are drawn as usual.
  const KindSet blocked = blocked_kinds();
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
    const auto entries = outbox.peek(want, config.max_fetch_bytes, claimed, blocked);
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
