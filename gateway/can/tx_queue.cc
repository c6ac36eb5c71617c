#include "gateway/can/tx_queue.h"

#include <stdexcept>
#include <utility>

#include <asio/post.hpp>

namespace fleetgw::can {

namespace {
constexpr uint32_t kStandardIdMask = 0x7FF;
constexpr uint8_t kClassicMaxLen = 8;
}  // namespace

bool is_sendable(const motinova::CanFrame& frame) {
  return frame.len <= kClassicMaxLen && frame.id <= kStandardIdMask;
}

TxQueue::TxQueue(asio::io_context& io, std::size_t limit, std::function<void()> drain)
    : io_(io), limit_(limit), drain_(std::move(drain)) {
  if (limit_ == 0) throw std::invalid_argument("tx_queue_limit must be > 0");
}

void TxQueue::stop() {
  started_ = false;
  alive_.reset();
}

bool TxQueue::push(const motinova::CanFrame& frame) {
  if (frames_.size() >= limit_) return false;
  frames_.push_back(frame);
  if (!held_ && started_) {
    held_ = true;
    asio::post(io_, [this, token = std::weak_ptr<int>(alive_)] {
      if (token.expired()) return;
      held_ = false;
      drain_();
    });
  }
  return true;
}

void TxQueue::pop(std::size_t count) {
  frames_.erase(frames_.begin(), frames_.begin() + static_cast<std::ptrdiff_t>(count));
}

std::size_t TxQueue::drop_all() {
  const std::size_t dropped = frames_.size();
  frames_.clear();
  return dropped;
}

}  // namespace fleetgw::can
