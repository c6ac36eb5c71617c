// Cuts an encoded application frame into classic CAN frames on one ID (spec §2.2): 8 bytes each,
// the last carrying the remaining 1..8 bytes. No sequence numbers, no flow control.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "motinova/can.h"
#include "motinova/frame.h"

namespace motinova {

inline constexpr std::size_t kMaxSegments = (kMaxFrameSize + 7) / 8;  // 33

inline std::size_t segment_count(std::size_t frame_bytes) {
  return (frame_bytes + 7) / 8;
}

// Calls `emit(const CanFrame&)` once per segment, in order.
template <typename Emit>
void segment(uint16_t can_id, std::span<const uint8_t> frame_bytes, Emit&& emit) {
  CanFrame can;
  can.id = can_id;
  for (std::size_t off = 0; off < frame_bytes.size(); off += 8) {
    const std::size_t n = std::min<std::size_t>(8, frame_bytes.size() - off);
    can.len = static_cast<uint8_t>(n);
    can.data = {};
    for (std::size_t i = 0; i < n; ++i) can.data[i] = frame_bytes[off + i];
    emit(can);
  }
}

std::vector<CanFrame> segment(uint16_t can_id, std::span<const uint8_t> frame_bytes);
// Encodes and segments in one step.
std::vector<CanFrame> segment(const AppFrame& frame, CrcOrder order = CrcOrder::kBig);

}  // namespace motinova
