#include "motinova/segmenter.h"

namespace motinova {

std::vector<CanFrame> segment(uint16_t can_id, std::span<const uint8_t> frame_bytes) {
  std::vector<CanFrame> out;
  out.reserve(segment_count(frame_bytes.size()));
  segment(can_id, frame_bytes, [&out](const CanFrame& f) { out.push_back(f); });
  return out;
}

std::vector<CanFrame> segment(const AppFrame& frame, CrcOrder order) {
  const auto bytes = encode_frame(frame, order);
  return segment(frame.can_id, bytes.span());
}

}  // namespace motinova
