// Byte-level helpers shared by the protocol library.
//
// Contract: pure functions, no allocation. FixedBytes<N> is a value type holding up to N bytes
// inline so that application frames can be passed around without touching the heap.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>

namespace motinova {

// Byte order of multi-byte DATA fields (spec §2.4, uncertain reading U2) and of the CRC field
// (U1). Big-endian is the documented best guess for both.
enum class ByteOrder : uint8_t { kBig, kLittle };

inline uint64_t read_uint(std::span<const uint8_t> bytes, ByteOrder order) {
  uint64_t value = 0;
  if (order == ByteOrder::kBig) {
    for (uint8_t b : bytes) value = (value << 8) | b;
  } else {
    for (std::size_t i = bytes.size(); i-- > 0;) value = (value << 8) | bytes[i];
  }
  return value;
}

inline void write_uint(std::span<uint8_t> out, uint64_t value, ByteOrder order) {
  const std::size_t n = out.size();
  for (std::size_t i = 0; i < n; ++i) {
    const uint8_t b = static_cast<uint8_t>(value >> (8 * i));
    if (order == ByteOrder::kBig) {
      out[n - 1 - i] = b;
    } else {
      out[i] = b;
    }
  }
}

// Sign-extends the low `bytes`*8 bits of `raw`.
inline int64_t sign_extend(uint64_t raw, std::size_t bytes) {
  if (bytes == 0 || bytes >= 8) return static_cast<int64_t>(raw);
  const unsigned bits = static_cast<unsigned>(bytes * 8);
  const uint64_t sign = uint64_t{1} << (bits - 1);
  const uint64_t mask = (uint64_t{1} << bits) - 1;
  raw &= mask;
  return static_cast<int64_t>((raw ^ sign) - sign);
}

// Up to N bytes stored inline.
template <std::size_t N>
class FixedBytes {
 public:
  FixedBytes() = default;
  explicit FixedBytes(std::span<const uint8_t> bytes) { assign(bytes); }

  void assign(std::span<const uint8_t> bytes) {
    if (bytes.size() > N) throw std::length_error("FixedBytes: too many bytes");
    std::copy(bytes.begin(), bytes.end(), data_.begin());
    size_ = static_cast<uint16_t>(bytes.size());
  }
  void resize(std::size_t n) {
    if (n > N) throw std::length_error("FixedBytes: too many bytes");
    if (n > size_) std::fill(data_.begin() + size_, data_.begin() + n, 0);
    size_ = static_cast<uint16_t>(n);
  }
  void clear() { size_ = 0; }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  static constexpr std::size_t capacity() { return N; }
  const uint8_t* data() const { return data_.data(); }
  uint8_t* data() { return data_.data(); }
  uint8_t operator[](std::size_t i) const { return data_[i]; }
  uint8_t& operator[](std::size_t i) { return data_[i]; }
  std::span<const uint8_t> span() const { return {data_.data(), size_}; }
  std::span<uint8_t> span() { return {data_.data(), size_}; }
  const uint8_t* begin() const { return data_.data(); }
  const uint8_t* end() const { return data_.data() + size_; }

  friend bool operator==(const FixedBytes& a, const FixedBytes& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end());
  }

 private:
  std::array<uint8_t, N> data_{};
  uint16_t size_ = 0;
};

}  // namespace motinova
