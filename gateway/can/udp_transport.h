// CAN frames over UDP between processes (simulator ↔ gateway on one host, or a bench bus
// bridged from another machine), in the wire format of cannelloni's UDP data packets (format
// version 2), so a cannelloni instance on a real bus can feed fleetgw directly:
//
//   u8 version (2) | u8 op code (0 = DATA) | u8 sequence number | u16 frame count (big-endian)
//   then per frame: u32 can_id (big-endian, with EFF/RTR/ERR flags) | u8 len | len data bytes
//   (RTR frames carry no data bytes; len with bit 0x80 marks a CAN FD frame followed by a flags
//   byte and up to 64 data bytes).
//
// Contract:
//  * Frames leave in order, as few datagrams as fit (at most kMaxDatagram bytes each): frames
//    passed to send() in one io_context turn go out together, with any still waiting for the
//    datagram in flight. send() never blocks and returns false when the bounded TxQueue
//    (tx_queue_limit frames, the datagram in flight included) is full.
//  * Received datagrams are validated completely before any frame is delivered: a malformed
//    datagram (short header, wrong version or op code, truncated frame, classic frame longer
//    than 8 bytes, trailing bytes) is rejected as a whole, logged (rate-limited) and counted;
//    datagrams from any endpoint other than the configured remote are rejected the same way.
//  * Like the SocketCAN acceptance filter, only standard data frames 0x700-0x7FF are delivered;
//    extended/remote frames and CAN FD frames are counted and skipped, error frames update
//    health() as on a live bus. The frame timestamp is the receive time (the Env's wall clock).
//  * Single-threaded: call everything on the io_context's thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <asio/io_context.hpp>
#include <asio/ip/udp.hpp>

#include "env/env.h"
#include "gateway/can/transport.h"
#include "gateway/can/tx_queue.h"

namespace fleetgw::can {

namespace cannelloni {
inline constexpr uint8_t kVersion = 2;
inline constexpr uint8_t kOpData = 0;
inline constexpr std::size_t kHeaderSize = 5;
inline constexpr uint8_t kFdLenFlag = 0x80;

// One CAN frame as carried on the wire (classic frames only are produced by fleetgw).
struct WireFrame {
  uint32_t can_id = 0;  // SocketCAN can_id with flags
  uint8_t len = 0;
  bool fd = false;
  std::array<uint8_t, 64> data{};
  friend bool operator==(const WireFrame&, const WireFrame&) = default;
};

struct Datagram {
  uint8_t sequence = 0;
  std::vector<WireFrame> frames;
};

// Encodes a data packet. Frames must be classic (len <= 8, no FD).
std::vector<uint8_t> encode(uint8_t sequence, std::span<const WireFrame> frames);
// Decodes and validates a whole datagram; on failure returns nullopt and sets `error` to a
// message naming the byte offset and what is wrong.
std::optional<Datagram> decode(std::span<const uint8_t> bytes, std::string& error);
}  // namespace cannelloni

struct UdpOptions {
  std::string local_address = "127.0.0.1";
  uint16_t local_port = 0;  // 0 = ephemeral (see local_port())
  std::string remote_address = "127.0.0.1";
  uint16_t remote_port = 0;  // 0 = not set yet (set_remote()); send() fails until then
  std::size_t tx_queue_limit = 1024;
};

struct UdpStats {
  uint64_t datagrams_rx = 0;
  uint64_t datagrams_tx = 0;
  uint64_t malformed_datagrams = 0;  // rejected by the decoder
  uint64_t foreign_datagrams = 0;    // from an endpoint other than the remote
  uint64_t filtered_frames = 0;      // well-formed but not standard data 0x700-0x7FF
  uint64_t unsupported_frames = 0;   // CAN FD
  uint64_t sequence_gaps = 0;        // datagrams missing according to the sequence numbers
};

class UdpTransport final : public Transport {
 public:
  // Maximum datagram fleetgw sends: stays below a 1500-byte Ethernet MTU.
  static constexpr std::size_t kMaxDatagram = 1400;

  // Binds the local socket; throws std::runtime_error naming the address/port on failure
  // (invalid address, port in use).
  // `env` (the wall clock that stamps received frames) must outlive the transport.
  UdpTransport(asio::io_context& io, UdpOptions options, Env& env = Env::system());
  ~UdpTransport() override;

  UdpTransport(const UdpTransport&) = delete;
  UdpTransport& operator=(const UdpTransport&) = delete;

  void start(FrameHandler on_frame, HealthHandler on_health) override;
  bool send(const motinova::CanFrame& frame) override;
  void stop() override;
  const BusHealth& health() const override { return health_; }
  std::string_view name() const override { return name_; }

  uint16_t local_port() const;
  void set_remote(const std::string& address, uint16_t port);
  const UdpStats& stats() const { return stats_; }

 private:
  void receive();
  void handle_datagram(std::size_t size);
  void reject(std::string_view what);
  void send_next();

  UdpOptions options_;
  Env& env_;
  std::string name_;
  asio::ip::udp::socket socket_;
  std::optional<asio::ip::udp::endpoint> remote_;
  asio::ip::udp::endpoint sender_;
  std::vector<uint8_t> rx_buffer_;

  TxQueue tx_;                        // held while a datagram is in flight
  std::vector<uint8_t> tx_datagram_;  // the datagram in flight
  uint8_t tx_sequence_ = 0;
  std::optional<uint8_t> rx_sequence_;

  FrameHandler on_frame_;
  HealthHandler on_health_;
  BusHealth health_;
  UdpStats stats_;
  bool started_ = false;
  bool stopped_ = false;
  uint64_t logged_rejects_ = 0;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

}  // namespace fleetgw::can
