// CAN-level vocabulary: classic CAN frames, the MOTINOVA node numbering and the CAN-ID scheme
// (spec §1.2-1.4): ID = 0x700 | (source << 4) | target, target 0 = broadcast.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace motinova {

// Microseconds since the Unix epoch (or since an arbitrary origin for monotonic sources).
using Micros = std::chrono::microseconds;

// A classic CAN 2.0A data frame.
struct CanFrame {
  uint32_t id = 0;  // 11-bit identifier
  uint8_t len = 0;  // DLC, 0..8
  std::array<uint8_t, 8> data{};

  std::span<const uint8_t> payload() const { return {data.data(), len}; }
  friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

// Node numbers of the V4.6.2 bus (§1.3). 0 is "broadcast" when used as a target.
enum class Node : uint8_t {
  kBroadcast = 0x0,
  kMc = 0x1,
  kBms = 0x2,
  kObc = 0x3,
  kHmi = 0x4,
  kCdl = 0x5,
  kIot = 0x6,
  kLock1 = 0x7,
  kLock2 = 0x8,
  kLock3 = 0x9,
  kLock4 = 0xA,
  kLock5 = 0xB,
};

inline constexpr uint32_t kMotinovaIdMask = 0x700;   // acceptance filter mask (§1.4)
inline constexpr uint32_t kMotinovaIdMatch = 0x700;  // acceptance filter match
inline constexpr int kLockCount = 5;

inline constexpr bool is_motinova_id(uint32_t id) {
  return id <= 0x7FF && (id & kMotinovaIdMask) == kMotinovaIdMatch;
}
inline constexpr uint16_t make_can_id(Node src, Node dst) {
  return static_cast<uint16_t>(0x700 | (static_cast<unsigned>(src) << 4) |
                               static_cast<unsigned>(dst));
}
inline constexpr Node source_of(uint32_t id) {
  return static_cast<Node>((id >> 4) & 0xF);
}
inline constexpr Node target_of(uint32_t id) {
  return static_cast<Node>(id & 0xF);
}

inline constexpr bool is_lock(Node n) {
  return n >= Node::kLock1 && n <= Node::kLock5;
}
// 0-based lock index (LOCK 1 = node 7 -> 0).
inline constexpr int lock_index(Node n) {
  return static_cast<int>(n) - 7;
}
inline constexpr Node lock_node(int index) {
  return static_cast<Node>(7 + index);
}

// Lower-case short name used in JSON and logs: "mc", "bms", "obc", "hmi", "cdl", "iot",
// "lock1".."lock5", "all" for broadcast, "node12".."node15" for reserved numbers.
std::string_view node_name(Node n);
std::optional<Node> node_from_name(std::string_view name);

}  // namespace motinova
