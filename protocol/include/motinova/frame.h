// The MOTINOVA application frame (spec §2.1):
//
//   55 AA | MODE | LENGTH | FUNCTION | n | DATA[n] | CRC32 (4) | F0      with n == LENGTH - 2
//
// Contract: encode_frame/parse_frame are pure and never allocate. parse_frame checks every
// structural rule and the CRC and says exactly which rule failed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "motinova/bytes.h"

namespace motinova {

inline constexpr uint8_t kHeader0 = 0x55;
inline constexpr uint8_t kHeader1 = 0xAA;
inline constexpr uint8_t kTail = 0xF0;
inline constexpr std::size_t kMaxData = 253;       // LENGTH <= 0xFF, n = LENGTH - 2
inline constexpr std::size_t kFrameOverhead = 11;  // header 2, mode, length, cmd 2, crc 4, tail
inline constexpr std::size_t kMaxFrameSize = kMaxData + kFrameOverhead;  // 264 bytes

// MODE byte. Other values are rejected as framing errors.
enum class Mode : uint8_t { kRead = 0x11, kWrite = 0x16, kReport = 0x0C };
bool is_valid_mode(uint8_t mode);
std::string_view mode_name(Mode m);  // "read", "write", "report"

// Order of CRC1..CRC4 in the frame (uncertain reading U1). kAuto accepts either on receive.
enum class CrcOrder : uint8_t { kBig, kLittle, kAuto };

struct AppFrame {
  uint16_t can_id = 0;
  Mode mode = Mode::kReport;
  uint8_t function = 0;
  FixedBytes<kMaxData> data;

  // The catalogue's COMMAND notation: function << 8 | n.
  uint16_t command() const { return static_cast<uint16_t>((function << 8) | data.size()); }
  std::size_t wire_size() const { return data.size() + kFrameOverhead; }
  friend bool operator==(const AppFrame&, const AppFrame&) = default;
};

// Every way a byte sequence can fail to be a frame. The reassembler adds its own kinds.
enum class FrameError : uint8_t {
  kNone = 0,
  kBadHeader,       // does not start with 55 AA
  kBadMode,         // MODE not 0x11/0x16/0x0C
  kBadLength,       // LENGTH < 2
  kLengthMismatch,  // n != LENGTH - 2
  kTruncated,       // fewer bytes than LENGTH + 9
  kBadTail,         // last byte not F0
  kBadCrc,          // CRC matches in neither accepted order
};
std::string_view frame_error_name(FrameError e);

struct ParseResult {
  FrameError error = FrameError::kNone;
  CrcOrder crc_seen = CrcOrder::kBig;  // which order matched (kBig or kLittle)
  AppFrame frame;
  bool ok() const { return error == FrameError::kNone; }
};

// Parses exactly one frame from `bytes` (which must hold at least LENGTH + 9 bytes; surplus
// bytes after the tail are ignored, as a sender may pad the last CAN frame).
ParseResult parse_frame(uint16_t can_id, std::span<const uint8_t> bytes, CrcOrder order);

// Writes the frame into `out` and returns its size. `order` kAuto encodes big-endian.
std::size_t encode_frame(const AppFrame& frame, CrcOrder order,
                         std::span<uint8_t, kMaxFrameSize> out);

// Convenience for tests and tools.
FixedBytes<kMaxFrameSize> encode_frame(const AppFrame& frame, CrcOrder order = CrcOrder::kBig);

// Builds a frame from its parts.
AppFrame make_frame(uint16_t can_id, Mode mode, uint8_t function, std::span<const uint8_t> data);
AppFrame make_frame(uint16_t can_id, Mode mode, uint8_t function, std::string_view ascii);

}  // namespace motinova
