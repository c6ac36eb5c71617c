#include "gateway/node/transport_sender.h"

#include <array>

#include "motinova/segmenter.h"

namespace fleetgw::node {

bool TransportSender::send(const motinova::AppFrame& frame) {
  std::array<uint8_t, motinova::kMaxFrameSize> buffer{};
  const std::size_t size = motinova::encode_frame(frame, crc_order_, buffer);
  bool ok = true;
  // The template overload emits segments without allocating; stop at the first refusal so a
  // half-queued message is not followed by more of its own tail.
  motinova::segment(frame.can_id, std::span<const uint8_t>(buffer.data(), size),
                    [&](const motinova::CanFrame& can) {
                      if (!ok) return;
                      if (transport_.send(can)) {
                        ++stats_.segments_sent;
                      } else {
                        ok = false;
                      }
                    });
  if (ok) {
    ++stats_.frames_sent;
  } else {
    ++stats_.frames_failed;
  }
  return ok;
}

}  // namespace fleetgw::node
