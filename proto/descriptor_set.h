// The fleetgw.v1 schema as compiled into the binary.
//
// The generated classes use protobuf's lite runtime (optimize_for = LITE_RUNTIME): the gateway
// only serializes and parses, and the full runtime's reflection costs about a megabyte of
// resident memory on the IoT node. What needs reflection -- JSON in `fleetgw watch`, the schema
// tests -- builds it from this: a serialized google.protobuf.FileDescriptorSet of every
// fleetgw/v1/*.proto, written by protoc at build time (--include_imports, dependency order).
#pragma once

#include <string_view>

namespace fleetgw::proto {

std::string_view descriptor_set_bytes();

}  // namespace fleetgw::proto
