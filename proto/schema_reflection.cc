#include "proto/schema_reflection.h"

#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/util/json_util.h>

#include <stdexcept>

#include "proto/descriptor_set.h"

namespace fleetgw::proto {

namespace pb = google::protobuf;

SchemaReflection::SchemaReflection() : pool_(&database_), factory_(&pool_) {
  pb::FileDescriptorSet set;
  const std::string_view bytes = descriptor_set_bytes();
  if (!set.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    throw std::runtime_error("embedded fleetgw.v1 descriptor set does not parse");
  }
  for (const auto& file : set.file()) {
    if (!database_.Add(file)) {
      throw std::runtime_error("embedded descriptor set: cannot add " + file.name());
    }
  }
  // Build everything now, so that a broken set fails here and not at the first message.
  for (const auto& file : set.file()) {
    if (pool_.FindFileByName(file.name()) == nullptr) {
      throw std::runtime_error("embedded descriptor set: " + file.name() + " does not build");
    }
  }
}

const pb::Descriptor& SchemaReflection::message_type(std::string_view full_name) const {
  const auto* d = pool_.FindMessageTypeByName(std::string(full_name));
  if (d == nullptr) {
    throw std::invalid_argument("no message type " + std::string(full_name) + " in fleetgw.v1");
  }
  return *d;
}

std::unique_ptr<pb::Message> SchemaReflection::parse(std::string_view full_name,
                                                     std::string_view bytes) const {
  const pb::Message* prototype = factory_.GetPrototype(&message_type(full_name));
  std::unique_ptr<pb::Message> message(prototype->New());
  if (!message->ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return nullptr;
  return message;
}

std::string SchemaReflection::to_json(const pb::Message& message) {
  std::string json;
  pb::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  (void)pb::util::MessageToJsonString(message, &json, options);
  return json;
}

}  // namespace fleetgw::proto
