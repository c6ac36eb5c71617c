// The record-kind table (proto/record_kinds.h) against the schema, and the uplink's Envelope
// splice against the generated code, for every kind:
//  * each kind's Envelope field exists in fleetgw.v1.Envelope's descriptor with that number and
//    that message type, and its stored payload type exists;
//  * its route publishes on its own topic;
//  * a record spliced from its stored bytes is byte-identical to the generated code's Envelope,
//    and a corrupted stored body is refused.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/envelope_writer.h"
#include "gateway/uplink/outbox_source.h"
#include "proto/record_kinds.h"
#include "proto/schema_reflection.h"

namespace fleetgw::uplink {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;

const proto::SchemaReflection& schema() {
  static const proto::SchemaReflection s;
  return s;
}

// Sets every field of `m` (messages to `depth`, one element per repeated field or map, so a
// map's order cannot differ between serialisers), with valid UTF-8 text.
void fill(Message& m, int depth) {
  const Descriptor* d = m.GetDescriptor();
  const Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const FieldDescriptor* f = d->field(i);
    if (f->real_containing_oneof() != nullptr && f->real_containing_oneof()->field(0) != f) {
      continue;  // one member per oneof
    }
    const bool rep = f->is_repeated();
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_INT32:
        rep ? r->AddInt32(&m, f, -7 - i) : r->SetInt32(&m, f, -7 - i);
        break;
      case FieldDescriptor::CPPTYPE_INT64:
        rep ? r->AddInt64(&m, f, 1'700'000'000'000'000 + i)
            : r->SetInt64(&m, f, 1'700'000'000'000'000 + i);
        break;
      case FieldDescriptor::CPPTYPE_UINT32:
        rep ? r->AddUInt32(&m, f, 300u + static_cast<unsigned>(i))
            : r->SetUInt32(&m, f, 300u + static_cast<unsigned>(i));
        break;
      case FieldDescriptor::CPPTYPE_UINT64:
        rep ? r->AddUInt64(&m, f, 1u << 20) : r->SetUInt64(&m, f, 1u << 20);
        break;
      case FieldDescriptor::CPPTYPE_DOUBLE:
        rep ? r->AddDouble(&m, f, 2.5) : r->SetDouble(&m, f, 2.5);
        break;
      case FieldDescriptor::CPPTYPE_FLOAT:
        rep ? r->AddFloat(&m, f, 1.5f) : r->SetFloat(&m, f, 1.5f);
        break;
      case FieldDescriptor::CPPTYPE_BOOL:
        rep ? r->AddBool(&m, f, true) : r->SetBool(&m, f, true);
        break;
      case FieldDescriptor::CPPTYPE_ENUM: {
        const int v = f->enum_type()->value(f->enum_type()->value_count() - 1)->number();
        rep ? r->AddEnumValue(&m, f, v) : r->SetEnumValue(&m, f, v);
        break;
      }
      case FieldDescriptor::CPPTYPE_STRING: {
        const std::string v = f->type() == FieldDescriptor::TYPE_BYTES
                                  ? std::string("\x00\xff\x01", 3)
                                  : "f\xc3\xa9ld-" + std::to_string(i);
        rep ? r->AddString(&m, f, v) : r->SetString(&m, f, v);
        break;
      }
      case FieldDescriptor::CPPTYPE_MESSAGE:
        if (depth <= 0) break;
        fill(rep ? *r->AddMessage(&m, f) : *r->MutableMessage(&m, f), depth - 1);
        break;
    }
  }
}

TEST(RecordKinds, EveryKindMatchesTheEnvelopeSchema) {
  const Descriptor& envelope = schema().message_type("fleetgw.v1.Envelope");
  std::set<int> fields;
  for (const auto& spec : records::kRecordKinds) {
    SCOPED_TRACE(std::string(spec.stored_name));
    const FieldDescriptor* f = envelope.FindFieldByNumber(spec.envelope_field);
    ASSERT_NE(f, nullptr) << "no Envelope field " << spec.envelope_field;
    ASSERT_NE(f->real_containing_oneof(), nullptr);
    EXPECT_EQ(f->real_containing_oneof()->name(), "body");
    ASSERT_EQ(f->type(), FieldDescriptor::TYPE_MESSAGE);
    EXPECT_EQ(f->message_type()->full_name(), spec.body_message);
    EXPECT_NO_THROW((void)schema().message_type(spec.stored_message));
    EXPECT_TRUE(fields.insert(spec.envelope_field).second) << "two kinds on one field";
    EXPECT_EQ(records::find_by_envelope_field(spec.envelope_field), &spec);
    EXPECT_EQ(records::find_by_topic_leaf(spec.topic_leaf), &spec);
    EXPECT_EQ(records::kind_from_stored_name(spec.stored_name), spec.kind);
    EXPECT_FALSE(spec.ingest_table.empty());
  }
  // The retained VehicleState is a body but no record.
  EXPECT_EQ(records::find_by_envelope_field(envelope.FindFieldByName("state")->number()), nullptr);
}

TEST(RecordKinds, EveryKindRoutesToItsOwnTopic) {
  const Topics topics("fleet/v1", "bike-7");
  for (const auto& spec : records::kRecordKinds) {
    const KindRoute* r = find_route(spec.stored_name);
    ASSERT_NE(r, nullptr) << spec.stored_name;
    EXPECT_EQ(r->spec, &spec);
    EXPECT_EQ(topics.*(r->topic), "fleet/v1/bike-7/" + std::string(spec.topic_leaf));
  }
  EXPECT_EQ(topics.command_result, "fleet/v1/bike-7/cmd/result") << "a wire contract";
  EXPECT_EQ(find_route("cmd_result"), nullptr) << "one name per kind";
}

// The splice writes what the generated code writes: the reference is the generated
// fleetgw.v1.Envelope (lite) holding the same body, serialised.
TEST(RecordKinds, SplicedEnvelopeIsByteIdenticalToTheGeneratedCodeForEveryKind) {
  const EnvelopeHeader h{"bike-1", 4242, 1'700'000'000'123'456, "0.9.1",
                         "0b9c2c1e-6f1d-4c4e-9d7e-2f5a3b1c0d9e"};
  for (const auto& spec : records::kRecordKinds) {
    if (spec.kind == records::RecordKind::kTelemetry) continue;  // batches: test_uplink_envelope
    SCOPED_TRACE(std::string(spec.stored_name));
    auto body = schema().parse(spec.stored_message, "");
    ASSERT_NE(body, nullptr);
    fill(*body, 3);
    const std::string stored = body->SerializeAsString();
    ASSERT_FALSE(stored.empty());

    const auto spliced = serialize_record(*find_route(spec.stored_name), h, stored);
    ASSERT_TRUE(spliced.has_value());

    // The same Envelope through the generated code: header + body field, parsed and written.
    v1::Envelope header_only;
    fill_header(header_only, h);
    std::string assembled = header_only.SerializeAsString();
    auto dynamic = schema().parse("fleetgw.v1.Envelope", assembled);
    ASSERT_NE(dynamic, nullptr);
    const FieldDescriptor* f = dynamic->GetDescriptor()->FindFieldByNumber(spec.envelope_field);
    ASSERT_TRUE(
        dynamic->GetReflection()->MutableMessage(dynamic.get(), f)->ParseFromString(stored));
    v1::Envelope generated;
    ASSERT_TRUE(generated.ParseFromString(dynamic->SerializeAsString()));
    EXPECT_EQ(static_cast<int>(generated.body_case()), spec.envelope_field);
    EXPECT_EQ(*spliced, generated.SerializeAsString());
  }
}

TEST(RecordKinds, ACorruptedStoredBodyIsRefusedForEveryKind) {
  const EnvelopeHeader h{"bike-1", 1, 2, "fw", "store"};
  const std::string corrupted[] = {
      std::string("\xff\xff\xff", 3),  // unterminated tag
      std::string("\x0a\x05"
                  "ab",
                  4),              // length beyond the end
      std::string("\x0c", 1),      // end-group without a start
      std::string("\x00\x01", 2),  // field number 0
  };
  for (const auto& spec : records::kRecordKinds) {
    for (const auto& bytes : corrupted) {
      EXPECT_FALSE(serialize_record(*find_route(spec.stored_name), h, bytes).has_value())
          << spec.stored_name << " " << ::testing::PrintToString(bytes);
    }
  }
}

}  // namespace
}  // namespace fleetgw::uplink
