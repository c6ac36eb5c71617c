// Writing outbox records as fleetgw.v1.Envelope messages, without parsing them.
//
// Why: a record is serialised once, where it is born (gateway/domain, the command service, the
// campaign service, the eviction encoder); the outbox keeps those bytes. The uplink writes the
// Envelope around them (protobuf wire format: an embedded message is tag + length + bytes): the
// header fields with the generated code, then the kind's body field spliced. Telemetry batches
// splice each stored sample the same way, setting its sequence.
//
// Contract:
//  * find_route() maps a record kind's stored name (outbox_source.h) to its entry of the
//    record-kind table (proto/record_kinds.h) and its topic; nullptr for an unknown kind.
//  * serialize_record() returns the Envelope of one non-telemetry record: bytes identical to
//    the generated code's (parse the body into the kind's field, fill the header,
//    SerializeAsString) for any body the generated code wrote (the only producer); tests/uplink
//    pin this for every kind. It walks the body's wire format first (tags, lengths, groups) and
//    returns nullopt, writing nothing, when it is not well-formed: a corrupted stored body never
//    leaves. Text fields are made valid UTF-8 where they are born (tests/command
//    test_hostile_strings), which the walk does not re-check.
//  * TelemetryBatchWriter::add() takes the stored bytes of one fleetgw.v1.TelemetrySample and the
//    record's outbox sequence. It checks that the bytes are well-formed wire format (tags, lengths,
//    groups) and returns false, adding nothing, when they are not. envelope() returns bytes
//    identical to building the same Envelope with the generated classes -- parse each sample,
//    set_sequence(seq), add it to the batch, SerializeAsString -- for any sample bytes that the
//    generated code wrote (the only producer); tests/uplink pin this.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/uplink/topics.h"
#include "proto/record_kinds.h"

namespace fleetgw::v1 {
class Envelope;
}

namespace fleetgw::uplink {

struct EnvelopeHeader {
  std::string_view vehicle_id;
  std::uint64_t sequence = 0;  // 0 for messages that are not outbox records
  std::int64_t created_us = 0;
  std::string_view firmware_version;
  std::string_view store_id;  // empty: not set (the last will)
};

struct KindRoute {
  const records::RecordKindSpec* spec;  // stored name, Envelope field, messages, ...
  const std::string Topics::*topic;
};

const KindRoute* find_route(std::string_view kind);
const KindRoute& route(records::RecordKind kind);

// True when `bytes` is well-formed protobuf wire format (what serialize_record() checks).
bool well_formed(std::string_view bytes);

// Sets the Envelope's header fields.
void fill_header(v1::Envelope& env, const EnvelopeHeader& header);

// A non-telemetry record as a serialized Envelope (its stored body spliced); nullopt if `body`
// is not well-formed wire format.
std::optional<std::string> serialize_record(const KindRoute& route, const EnvelopeHeader& header,
                                            std::string_view body);

// One stored sample, checked and measured, ready to be spliced (views into the stored bytes).
struct SampleSplice {
  std::string_view head;  // the stored bytes before a stored sequence field (usually empty)
  std::string_view tail;  // the stored bytes after it (usually all of them)
  std::uint64_t seq = 0;
  std::size_t size = 0;  // serialized sample size with `seq`
  // Bytes it adds to the batch as the uplink accounts them (size + 4 for tag and length).
  std::size_t accounted_size() const { return size + 4; }
};

class TelemetryBatchWriter {
 public:
  // Checks and measures one stored sample; nullopt if it is not well-formed wire format.
  static std::optional<SampleSplice> prepare(std::string_view stored_sample, std::uint64_t seq);
  void add(const SampleSplice& sample);
  // prepare() + add(); false (nothing added) if `stored_sample` is not well-formed.
  bool add(std::string_view stored_sample, std::uint64_t seq);
  static std::optional<std::size_t> accounted_size(std::string_view stored_sample,
                                                   std::uint64_t seq);

  std::size_t samples() const { return samples_; }
  bool empty() const { return samples_ == 0; }
  // The complete Envelope (header + telemetry batch); leaves the writer empty.
  std::string take_envelope(const EnvelopeHeader& header);

 private:
  std::string batch_;  // TelemetryBatch wire bytes: repeated (tag 1, length, sample)
  std::size_t samples_ = 0;
};

}  // namespace fleetgw::uplink
