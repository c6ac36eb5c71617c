// Wire-compatibility check of the fleetgw.v1 schema against a committed descriptor snapshot.
//
// Contract: compare() lists every change from `before` to `after` that can break an existing
// producer or consumer -- a message, field or enum value removed without reserving its number
// AND name, a field renumbered, retyped, made repeated/singular, moved into or out of a oneof,
// or a reserved number or name reused. Additions are compatible and produce nothing. Each
// problem names the full field path, e.g. "fleetgw.v1.RideRecord.energy_mwh (number 12) ...".
#pragma once

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::testing {

// The FileDescriptorProto of every fleetgw.v1 file in the generated descriptor pool, by name.
google::protobuf::FileDescriptorSet current_fleetgw_descriptors();

// Text format of a descriptor set (the snapshot file format), and back (throws on bad text).
std::string to_snapshot_text(const google::protobuf::FileDescriptorSet& set);
google::protobuf::FileDescriptorSet from_snapshot_text(const std::string& text);

// The committed snapshot file at `path` (FLEETGW_PROTO_SNAPSHOT), parsed; throws when the file
// is missing or not a snapshot.
google::protobuf::FileDescriptorSet load_snapshot(const std::string& path);

// The field `name` of the top-level message `message` (short name, e.g. "CommandResult") in
// `set`; nullptr when either is absent.
const google::protobuf::FieldDescriptorProto* find_field(
    const google::protobuf::FileDescriptorSet& set, std::string_view message,
    std::string_view name);

// Builds every file of `set` into `pool`, each after the files it imports (an older schema
// for "an old reader parses the new bytes" tests). Returns what went wrong, empty on success.
std::string build_pool(const google::protobuf::FileDescriptorSet& set,
                       google::protobuf::DescriptorPool& pool);

std::vector<std::string> compare(const google::protobuf::FileDescriptorSet& before,
                                 const google::protobuf::FileDescriptorSet& after);

}  // namespace fleetgw::testing
