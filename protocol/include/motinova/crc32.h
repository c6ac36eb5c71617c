// The MOTINOVA CRC32 (spec §2.3).
//
// It is the STM32 CRC unit (CRC-32/MPEG-2 core: polynomial 0x04C11DB7, init 0xFFFFFFFF, no
// reflection, no final XOR) fed one 32-bit word per input byte, the word being 0x000000bb. It is
// NOT the common zlib CRC-32. The CRC of an application frame also covers the 2-byte CAN ID,
// inserted (high byte first) after the 55 AA header, although the ID itself is not transmitted in
// the frame.
#pragma once

#include <cstdint>
#include <span>

namespace motinova {

inline constexpr uint32_t kCrcInit = 0xFFFFFFFFu;

// Continues a CRC over `data`, starting from `state` (kCrcInit for a fresh CRC).
uint32_t crc32_update(uint32_t state, std::span<const uint8_t> data);

inline uint32_t crc32(std::span<const uint8_t> data) {
  return crc32_update(kCrcInit, data);
}

// CRC of an application frame on `can_id`: covers 55 AA, then the ID (high byte first), then
// MODE, LENGTH, COMMAND and DATA. `frame_body` starts at the 55 AA header and ends with the last
// DATA byte.
uint32_t frame_crc(uint16_t can_id, std::span<const uint8_t> frame_body);

}  // namespace motinova
