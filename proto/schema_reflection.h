// Reflection over the fleetgw.v1 schema without the generated classes' descriptors.
//
// Contract: SchemaReflection() builds a DescriptorPool from descriptor_set_bytes() (throws
// std::runtime_error if that set does not build, which a build-time protoc run rules out).
// parse() returns nullptr when the bytes are not a valid message of that type; an unknown type
// name throws std::invalid_argument (a programming error, not bad input).
// to_json() prints with the .proto field names, as the backend's documentation uses them.
// Needs protobuf's full runtime: link fleetgw_proto_reflection only into tools and tests that
// need it.
#pragma once

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor_database.h>
#include <google/protobuf/dynamic_message.h>
#include <google/protobuf/message.h>

#include <memory>
#include <string>
#include <string_view>

namespace fleetgw::proto {

class SchemaReflection {
 public:
  SchemaReflection();

  const google::protobuf::DescriptorPool& pool() const { return pool_; }
  // The message type with this full name ("fleetgw.v1.Envelope"); throws std::invalid_argument
  // for a name the schema does not have.
  const google::protobuf::Descriptor& message_type(std::string_view full_name) const;
  std::unique_ptr<google::protobuf::Message> parse(std::string_view full_name,
                                                   std::string_view bytes) const;
  static std::string to_json(const google::protobuf::Message& message);

 private:
  google::protobuf::SimpleDescriptorDatabase database_;
  google::protobuf::DescriptorPool pool_;
  mutable google::protobuf::DynamicMessageFactory factory_;
};

}  // namespace fleetgw::proto
