#include "gateway/uplink/envelope_writer.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/wire_format_lite.h>

#include <array>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/outbox_source.h"

namespace fleetgw::uplink {

namespace {

using google::protobuf::internal::WireFormatLite;
using google::protobuf::io::CodedInputStream;
using google::protobuf::io::CodedOutputStream;

// One route per record kind, in RecordKind order, derived from the record-kind table and the
// topic table.
constexpr std::array<KindRoute, records::kRecordKinds.size()> make_routes() {
  std::array<KindRoute, records::kRecordKinds.size()> out{};
  for (std::size_t i = 0; i < out.size(); ++i) {
    const auto& spec = records::kRecordKinds[i];
    const TopicSpec* topic = record_kind_topic(spec.kind);
    out[i] = KindRoute{&spec, topic != nullptr ? topic->member : nullptr};
  }
  return out;
}
constexpr auto kRoutes = make_routes();

constexpr bool every_kind_has_a_topic() {
  for (const auto& r : kRoutes) {
    if (r.topic == nullptr) return false;
  }
  return true;
}
static_assert(every_kind_has_a_topic(), "a record kind without a kTopicTable entry (topics.h)");

// Field numbers of the wire format we write by hand (proto/fleetgw/v1/*.proto).
constexpr int kSampleSequenceField = 1;  // TelemetrySample.sequence (uint64)
constexpr int kBatchSamplesField = 1;    // TelemetryBatch.samples
constexpr int kEnvelopeTelemetryField =
    records::spec(records::RecordKind::kTelemetry).envelope_field;

constexpr std::uint32_t kSequenceTag =
    (kSampleSequenceField << 3) | WireFormatLite::WIRETYPE_VARINT;

// The stored sample without any sequence field, as up to two spans (the generated code writes
// the sequence first, so in practice `head` is empty and `tail` is what follows it).
struct SampleParts {
  std::string_view head;
  std::string_view tail;
};

// Walks the wire format of `bytes`: false if it is malformed. A varint field 1 (the sequence the
// uplink sets) is cut out; the generated code only ever writes it first, if at all.
std::optional<SampleParts> split_sample(std::string_view bytes) {
  CodedInputStream in(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                      static_cast<int>(bytes.size()));
  SampleParts parts{{}, bytes};
  bool cut = false;
  while (true) {
    const int start = in.CurrentPosition();
    if (static_cast<std::size_t>(start) == bytes.size()) break;
    const std::uint32_t tag = in.ReadTag();
    if (tag == 0) return std::nullopt;  // a truncated tag, or field number 0
    if (WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_END_GROUP) {
      return std::nullopt;
    }
    if (!WireFormatLite::SkipField(&in, tag)) return std::nullopt;
    if (tag == kSequenceTag) {
      if (cut) return std::nullopt;  // two sequences: not written by us; refuse
      cut = true;
      parts.head = bytes.substr(0, static_cast<std::size_t>(start));
      parts.tail = bytes.substr(static_cast<std::size_t>(in.CurrentPosition()));
    }
  }
  if (static_cast<std::size_t>(in.CurrentPosition()) != bytes.size()) return std::nullopt;
  return parts;
}

std::size_t sample_size(const SampleParts& p, std::uint64_t seq) {
  const std::size_t sequence = seq == 0 ? 0 : 1 + CodedOutputStream::VarintSize64(seq);
  return p.head.size() + sequence + p.tail.size();
}

void append_varint(std::string& out, std::uint64_t v) {
  std::uint8_t buf[10];
  const auto* end = CodedOutputStream::WriteVarint64ToArray(v, buf);
  out.append(reinterpret_cast<const char*>(buf), static_cast<std::size_t>(end - buf));
}

// The tag of length-delimited field `field` (a varint: two bytes from field 16 on).
void append_tag(std::string& out, int field) {
  append_varint(
      out, (static_cast<std::uint32_t>(field) << 3) | WireFormatLite::WIRETYPE_LENGTH_DELIMITED);
}

}  // namespace

const KindRoute* find_route(std::string_view kind) {
  const auto k = records::kind_from_stored_name(kind);
  return k ? &kRoutes[static_cast<std::size_t>(*k)] : nullptr;
}

const KindRoute& route(records::RecordKind kind) {
  return kRoutes[static_cast<std::size_t>(kind)];
}

bool well_formed(std::string_view bytes) {
  CodedInputStream in(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                      static_cast<int>(bytes.size()));
  while (static_cast<std::size_t>(in.CurrentPosition()) != bytes.size()) {
    const std::uint32_t tag = in.ReadTag();
    if (tag == 0) return false;  // a truncated tag, or field number 0
    if (WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_END_GROUP) return false;
    if (!WireFormatLite::SkipField(&in, tag)) return false;
  }
  return true;
}

void fill_header(v1::Envelope& env, const EnvelopeHeader& h) {
  env.set_vehicle_id(std::string(h.vehicle_id));
  env.set_sequence(h.sequence);
  env.set_created_at_us(h.created_us);
  env.set_gateway_fw_version(std::string(h.firmware_version));
  env.set_store_id(std::string(h.store_id));
}

std::optional<std::string> serialize_record(const KindRoute& route, const EnvelopeHeader& header,
                                            std::string_view body) {
  if (!well_formed(body)) return std::nullopt;
  v1::Envelope env;
  fill_header(env, header);
  std::string out;
  out.reserve(env.ByteSizeLong() + body.size() + 8);
  env.AppendToString(&out);
  // The generated code writes fields in number order; the body's number (>= 10) follows every
  // header field's (1..5), and a oneof has one member set: the splice is byte-identical.
  append_tag(out, route.spec->envelope_field);
  append_varint(out, body.size());
  out.append(body);
  return out;
}

std::optional<SampleSplice> TelemetryBatchWriter::prepare(std::string_view stored_sample,
                                                          std::uint64_t seq) {
  const auto parts = split_sample(stored_sample);
  if (!parts) return std::nullopt;
  return SampleSplice{parts->head, parts->tail, seq, sample_size(*parts, seq)};
}

void TelemetryBatchWriter::add(const SampleSplice& sample) {
  batch_.push_back(
      static_cast<char>((kBatchSamplesField << 3) | WireFormatLite::WIRETYPE_LENGTH_DELIMITED));
  append_varint(batch_, sample.size);
  // Field 1 first, as the generated serializer orders fields by number.
  if (sample.seq != 0) {
    batch_.push_back(static_cast<char>(kSequenceTag));
    append_varint(batch_, sample.seq);
  }
  batch_.append(sample.head);
  batch_.append(sample.tail);
  ++samples_;
}

bool TelemetryBatchWriter::add(std::string_view stored_sample, std::uint64_t seq) {
  const auto sample = prepare(stored_sample, seq);
  if (sample) add(*sample);
  return sample.has_value();
}

std::optional<std::size_t> TelemetryBatchWriter::accounted_size(std::string_view stored_sample,
                                                                std::uint64_t seq) {
  const auto sample = prepare(stored_sample, seq);
  if (!sample) return std::nullopt;
  return sample->accounted_size();
}

std::string TelemetryBatchWriter::take_envelope(const EnvelopeHeader& header) {
  v1::Envelope env;
  fill_header(env, header);
  std::string out;
  out.reserve(env.ByteSizeLong() + batch_.size() + 8);
  env.AppendToString(&out);
  append_tag(out, kEnvelopeTelemetryField);
  append_varint(out, batch_.size());
  out.append(batch_);
  batch_.clear();
  samples_ = 0;
  return out;
}

}  // namespace fleetgw::uplink
