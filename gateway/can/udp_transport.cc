#include "gateway/can/udp_transport.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include <spdlog/spdlog.h>
#include <asio/ip/address.hpp>
#include <asio/post.hpp>

#include "gateway/can/candump.h"
#include "gateway/can/error_frame.h"

namespace fleetgw::can {

namespace cannelloni {

std::vector<uint8_t> encode(uint8_t sequence, std::span<const WireFrame> frames) {
  if (frames.size() > 0xFFFF) throw std::invalid_argument("cannelloni: too many frames");
  std::vector<uint8_t> out;
  out.reserve(kHeaderSize + frames.size() * 13);
  out.push_back(kVersion);
  out.push_back(kOpData);
  out.push_back(sequence);
  out.push_back(static_cast<uint8_t>(frames.size() >> 8));
  out.push_back(static_cast<uint8_t>(frames.size() & 0xFF));
  for (const WireFrame& f : frames) {
    if (f.fd || f.len > 8) throw std::invalid_argument("cannelloni: only classic frames encoded");
    for (int shift = 24; shift >= 0; shift -= 8) {
      out.push_back(static_cast<uint8_t>(f.can_id >> shift));
    }
    out.push_back(f.len);
    // cannelloni sends no data bytes for remote frames, whatever their DLC.
    if ((f.can_id & candump::kRtrFlag) == 0) {
      out.insert(out.end(), f.data.begin(), f.data.begin() + f.len);
    }
  }
  return out;
}

std::optional<Datagram> decode(std::span<const uint8_t> b, std::string& error) {
  auto fail = [&error](std::size_t offset, const std::string& what) {
    error = "byte " + std::to_string(offset) + ": " + what;
    return std::nullopt;
  };
  if (b.size() < kHeaderSize) {
    return fail(0, "datagram of " + std::to_string(b.size()) + " bytes is shorter than the " +
                       std::to_string(kHeaderSize) + "-byte header");
  }
  if (b[0] != kVersion) {
    return fail(0, "unsupported version " + std::to_string(b[0]) + " (expected " +
                       std::to_string(kVersion) + ")");
  }
  if (b[1] != kOpData) return fail(1, "op code " + std::to_string(b[1]) + " is not DATA (0)");
  Datagram d;
  d.sequence = b[2];
  const std::size_t count = (std::size_t{b[3]} << 8) | b[4];
  std::size_t pos = kHeaderSize;
  d.frames.reserve(std::min<std::size_t>(count, b.size() / 5));
  for (std::size_t i = 0; i < count; ++i) {
    if (b.size() - pos < 5) {
      return fail(pos, "frame " + std::to_string(i + 1) + " of " + std::to_string(count) +
                           " truncated (header needs 5 bytes, " + std::to_string(b.size() - pos) +
                           " left)");
    }
    WireFrame f;
    f.can_id = (uint32_t{b[pos]} << 24) | (uint32_t{b[pos + 1]} << 16) |
               (uint32_t{b[pos + 2]} << 8) | uint32_t{b[pos + 3]};
    const uint8_t raw_len = b[pos + 4];
    const std::size_t frame_pos = pos;
    pos += 5;
    f.fd = (raw_len & kFdLenFlag) != 0;
    f.len = static_cast<uint8_t>(raw_len & ~kFdLenFlag);
    if (f.fd) {
      if (pos >= b.size())
        return fail(pos, "CAN FD frame " + std::to_string(i + 1) + ": missing flags byte");
      ++pos;  // FD flags: not used by fleetgw
      if (f.len > 64)
        return fail(frame_pos + 4, "CAN FD length " + std::to_string(f.len) + " > 64");
    } else if (f.len > 8) {
      return fail(frame_pos + 4, "classic CAN frame " + std::to_string(i + 1) + " has length " +
                                     std::to_string(f.len) + " > 8");
    }
    if ((f.can_id & candump::kRtrFlag) == 0) {
      if (b.size() - pos < f.len) {
        return fail(pos, "frame " + std::to_string(i + 1) + " truncated (" + std::to_string(f.len) +
                             " data bytes announced, " + std::to_string(b.size() - pos) + " left)");
      }
      std::copy_n(b.begin() + static_cast<std::ptrdiff_t>(pos), f.len, f.data.begin());
      pos += f.len;
    }
    d.frames.push_back(f);
  }
  if (pos != b.size()) {
    return fail(pos, std::to_string(b.size() - pos) + " trailing bytes after " +
                         std::to_string(count) + " frames");
  }
  return d;
}

}  // namespace cannelloni

namespace {

asio::ip::udp::endpoint make_endpoint(const std::string& address, uint16_t port, const char* role) {
  std::error_code ec;
  const auto addr = asio::ip::make_address(address, ec);
  if (ec) {
    throw std::runtime_error(std::string("UDP CAN transport: invalid ") + role + " address '" +
                             address + "': " + ec.message());
  }
  return {addr, port};
}

}  // namespace

UdpTransport::UdpTransport(asio::io_context& io, UdpOptions options, Env& env)
    : options_(std::move(options)),
      env_(env),
      socket_(io),
      rx_buffer_(65536),
      tx_(io, options_.tx_queue_limit, [this] { send_next(); }) {
  const auto local = make_endpoint(options_.local_address, options_.local_port, "local");
  std::error_code ec;
  socket_.open(local.protocol(), ec);
  if (!ec) socket_.bind(local, ec);
  if (ec) {
    throw std::runtime_error("UDP CAN transport: cannot bind " + options_.local_address + ":" +
                             std::to_string(options_.local_port) + ": " + ec.message());
  }
  if (options_.remote_port != 0) set_remote(options_.remote_address, options_.remote_port);
  name_ = "udp:" + options_.local_address + ":" + std::to_string(local_port());
}

UdpTransport::~UdpTransport() {
  stop();
}

uint16_t UdpTransport::local_port() const {
  std::error_code ec;
  const auto ep = socket_.local_endpoint(ec);
  return ec ? 0 : ep.port();
}

void UdpTransport::set_remote(const std::string& address, uint16_t port) {
  remote_ = make_endpoint(address, port, "remote");
}

void UdpTransport::start(FrameHandler on_frame, HealthHandler on_health) {
  if (started_) throw std::logic_error("UdpTransport::start called twice");
  started_ = true;
  on_frame_ = std::move(on_frame);
  on_health_ = std::move(on_health);
  health_.state = ControllerState::kUp;
  health_.detail = "listening on " + options_.local_address + ":" + std::to_string(local_port());
  if (on_health_) on_health_(health_);
  if (stopped_) return;
  receive();
  tx_.start();
  send_next();
}

bool UdpTransport::send(const motinova::CanFrame& frame) {
  if (stopped_ || !remote_ || !is_sendable(frame) || !tx_.push(frame)) {
    ++health_.tx_failures;
    return false;
  }
  return true;
}

void UdpTransport::stop() {
  stopped_ = true;
  alive_.reset();
  tx_.stop();
  std::error_code ignored;
  socket_.close(ignored);
}

void UdpTransport::send_next() {
  if (tx_.held() || tx_.empty() || stopped_) return;
  // One datagram with as many queued frames as fit, packed by encoded size (5 bytes of frame
  // header plus the data bytes). The frames stay queued (and count against the limit) until
  // the socket has taken the datagram.
  std::vector<cannelloni::WireFrame> frames;
  std::size_t size = cannelloni::kHeaderSize;
  while (frames.size() < tx_.size()) {
    const motinova::CanFrame& f = tx_[frames.size()];
    const std::size_t frame_size = 5 + f.len;
    if (!frames.empty() && size + frame_size > kMaxDatagram) break;
    size += frame_size;
    cannelloni::WireFrame& w = frames.emplace_back();
    w.can_id = f.id;
    w.len = f.len;
    std::copy_n(f.data.begin(), f.len, w.data.begin());
  }
  tx_datagram_ = cannelloni::encode(tx_sequence_++, frames);
  tx_.hold();
  socket_.async_send_to(asio::buffer(tx_datagram_), *remote_,
                        [this, frames = frames.size(), token = std::weak_ptr<int>(alive_)](
                            const std::error_code& ec, std::size_t) {
                          if (token.expired()) return;
                          tx_.release();
                          tx_.pop(frames);
                          if (ec) {
                            // UDP has no link to lose; a failed send (e.g. ICMP unreachable
                            // reported back) costs this datagram only.
                            health_.tx_failures += frames;
                            spdlog::warn("UDP CAN {}: send failed: {}", name_, ec.message());
                          } else {
                            ++stats_.datagrams_tx;
                            health_.tx_frames += frames;
                          }
                          send_next();
                        });
}

void UdpTransport::receive() {
  socket_.async_receive_from(
      asio::buffer(rx_buffer_), sender_,
      [this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec, std::size_t size) {
        if (token.expired() || ec == asio::error::operation_aborted) return;
        if (ec) {
          // ECONNREFUSED and friends: the peer is not listening yet. Not fatal for a tunnel.
          spdlog::debug("UDP CAN {}: receive error: {}", name_, ec.message());
        } else {
          handle_datagram(size);
          if (token.expired() || stopped_) return;
        }
        receive();
      });
}

void UdpTransport::reject(std::string_view what) {
  // Rate-limited: a misconfigured sender must not flood the log.
  ++logged_rejects_;
  if (logged_rejects_ <= 10 || logged_rejects_ % 1000 == 0) {
    spdlog::warn("UDP CAN {}: rejected datagram from {}:{}: {} ({} rejected so far)", name_,
                 sender_.address().to_string(), sender_.port(), what, logged_rejects_);
  }
}

void UdpTransport::handle_datagram(std::size_t size) {
  if (remote_ && sender_ != *remote_) {
    ++stats_.foreign_datagrams;
    reject("sender is not the configured remote " + remote_->address().to_string() + ":" +
           std::to_string(remote_->port()));
    return;
  }
  std::string error;
  const auto d = cannelloni::decode(std::span<const uint8_t>(rx_buffer_.data(), size), error);
  if (!d) {
    ++stats_.malformed_datagrams;
    reject(error);
    return;
  }
  ++stats_.datagrams_rx;
  if (rx_sequence_) {
    const auto expected = static_cast<uint8_t>(*rx_sequence_ + 1);
    if (d->sequence != expected) {
      stats_.sequence_gaps += static_cast<uint8_t>(d->sequence - expected);
    }
  }
  rx_sequence_ = d->sequence;

  const motinova::Micros now = env_.wall_now();
  const std::weak_ptr<int> token = alive_;
  for (const cannelloni::WireFrame& w : d->frames) {
    if (w.fd) {
      ++stats_.unsupported_frames;
      continue;
    }
    if (w.can_id & candump::kErrFlag) {
      ++health_.error_frames;
      const auto info = interpret_error_frame(w.can_id & candump::kEffMask,
                                              std::span<const uint8_t>(w.data.data(), w.len));
      spdlog::warn("UDP CAN {}: CAN error frame: {}", name_, info.description);
      health_.state = info.state.value_or(health_.state);
      health_.detail = info.description;
      if (on_health_) on_health_(health_);
    } else if ((w.can_id & (candump::kEffFlag | candump::kRtrFlag)) != 0 ||
               !motinova::is_motinova_id(w.can_id)) {
      ++stats_.filtered_frames;
      continue;
    } else {
      motinova::CanFrame f;
      f.id = w.can_id;
      f.len = w.len;
      std::copy_n(w.data.begin(), w.len, f.data.begin());
      ++health_.rx_frames;
      if (on_frame_) on_frame_(f, now);
    }
    if (token.expired() || stopped_) return;
  }
}

}  // namespace fleetgw::can
