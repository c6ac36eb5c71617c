#include "motinova/frame.h"

#include <algorithm>

#include "motinova/crc32.h"

namespace motinova {

bool is_valid_mode(uint8_t mode) {
  return mode == static_cast<uint8_t>(Mode::kRead) || mode == static_cast<uint8_t>(Mode::kWrite) ||
         mode == static_cast<uint8_t>(Mode::kReport);
}

std::string_view mode_name(Mode m) {
  switch (m) {
    case Mode::kRead:
      return "read";
    case Mode::kWrite:
      return "write";
    case Mode::kReport:
      return "report";
  }
  return "invalid";
}

std::string_view frame_error_name(FrameError e) {
  switch (e) {
    case FrameError::kNone:
      return "none";
    case FrameError::kBadHeader:
      return "bad_header";
    case FrameError::kBadMode:
      return "bad_mode";
    case FrameError::kBadLength:
      return "bad_length";
    case FrameError::kLengthMismatch:
      return "length_mismatch";
    case FrameError::kTruncated:
      return "truncated";
    case FrameError::kBadTail:
      return "bad_tail";
    case FrameError::kBadCrc:
      return "bad_crc";
  }
  return "unknown";
}

ParseResult parse_frame(uint16_t can_id, std::span<const uint8_t> bytes, CrcOrder order) {
  ParseResult r;
  auto fail = [&r](FrameError e) {
    r.error = e;
    return r;
  };
  if (bytes.size() < 2 || bytes[0] != kHeader0 || bytes[1] != kHeader1) {
    return fail(FrameError::kBadHeader);
  }
  if (bytes.size() < 4) return fail(FrameError::kTruncated);
  if (!is_valid_mode(bytes[2])) return fail(FrameError::kBadMode);
  const std::size_t length = bytes[3];
  if (length < 2) return fail(FrameError::kBadLength);
  const std::size_t total = length + 9;
  if (bytes.size() < total) return fail(FrameError::kTruncated);
  if (bytes[5] != length - 2) return fail(FrameError::kLengthMismatch);
  if (bytes[total - 1] != kTail) return fail(FrameError::kBadTail);

  const std::size_t body = 4 + length;  // up to the end of DATA
  const uint32_t crc = frame_crc(can_id, bytes.first(body));
  const uint32_t be = static_cast<uint32_t>(read_uint(bytes.subspan(body, 4), ByteOrder::kBig));
  const uint32_t le = static_cast<uint32_t>(read_uint(bytes.subspan(body, 4), ByteOrder::kLittle));
  if ((order == CrcOrder::kBig || order == CrcOrder::kAuto) && crc == be) {
    r.crc_seen = CrcOrder::kBig;
  } else if ((order == CrcOrder::kLittle || order == CrcOrder::kAuto) && crc == le) {
    r.crc_seen = CrcOrder::kLittle;
  } else {
    return fail(FrameError::kBadCrc);
  }
  r.frame.can_id = can_id;
  r.frame.mode = static_cast<Mode>(bytes[2]);
  r.frame.function = bytes[4];
  r.frame.data.assign(bytes.subspan(6, length - 2));
  return r;
}

std::size_t encode_frame(const AppFrame& frame, CrcOrder order,
                         std::span<uint8_t, kMaxFrameSize> out) {
  const std::size_t n = frame.data.size();
  out[0] = kHeader0;
  out[1] = kHeader1;
  out[2] = static_cast<uint8_t>(frame.mode);
  out[3] = static_cast<uint8_t>(n + 2);
  out[4] = frame.function;
  out[5] = static_cast<uint8_t>(n);
  std::copy(frame.data.begin(), frame.data.end(), out.begin() + 6);
  const std::size_t body = 6 + n;
  const uint32_t crc = frame_crc(frame.can_id, std::span<const uint8_t>(out.data(), body));
  write_uint(out.subspan(body, 4), crc,
             order == CrcOrder::kLittle ? ByteOrder::kLittle : ByteOrder::kBig);
  out[body + 4] = kTail;
  return body + 5;
}

FixedBytes<kMaxFrameSize> encode_frame(const AppFrame& frame, CrcOrder order) {
  FixedBytes<kMaxFrameSize> out;
  out.resize(kMaxFrameSize);
  const std::size_t size =
      encode_frame(frame, order, std::span<uint8_t, kMaxFrameSize>(out.data(), kMaxFrameSize));
  out.resize(size);
  return out;
}

AppFrame make_frame(uint16_t can_id, Mode mode, uint8_t function, std::span<const uint8_t> data) {
  AppFrame f;
  f.can_id = can_id;
  f.mode = mode;
  f.function = function;
  f.data.assign(data);
  return f;
}

AppFrame make_frame(uint16_t can_id, Mode mode, uint8_t function, std::string_view ascii) {
  return make_frame(
      can_id, mode, function,
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(ascii.data()), ascii.size()));
}

}  // namespace motinova
