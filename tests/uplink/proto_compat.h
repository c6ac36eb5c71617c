// Wire-compatibility check of the fleetgw.v1 schema against a committed descriptor snapshot.
//
// Contract: compare() lists every change from `before` to `after` that can break an existing
// producer or consumer -- a message, field or enum value removed without reserving its number
// AND name, a field renumbered, retyped, made repeated/singular, moved into or out of a oneof,
// or a reserved number or name reused. Additions are compatible and produce nothing. Each
// problem names the full field path, e.g. "fleetgw.v1.RideRecord.energy_mwh (number 12) ...".
#pragma once

#include <google/protobuf/descriptor.pb.h>

#include <string>
#include <vector>

namespace fleetgw::testing {

// The FileDescriptorProto of every fleetgw.v1 file in the generated descriptor pool, by name.
google::protobuf::FileDescriptorSet current_fleetgw_descriptors();

// Text format of a descriptor set (the snapshot file format), and back (throws on bad text).
std::string to_snapshot_text(const google::protobuf::FileDescriptorSet& set);
google::protobuf::FileDescriptorSet from_snapshot_text(const std::string& text);

std::vector<std::string> compare(const google::protobuf::FileDescriptorSet& before,
                                 const google::protobuf::FileDescriptorSet& after);

}  // namespace fleetgw::testing
