// Helpers shared by the protocol tests.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "motinova/can.h"
#include "motinova/reassembler.h"

namespace motinova::test {

inline std::vector<uint8_t> hex(std::string_view text) {
  std::vector<uint8_t> out;
  int nibble = -1;
  for (char c : text) {
    int v;
    if (c >= '0' && c <= '9')
      v = c - '0';
    else if (c >= 'a' && c <= 'f')
      v = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F')
      v = c - 'A' + 10;
    else
      continue;
    if (nibble < 0) {
      nibble = v;
    } else {
      out.push_back(static_cast<uint8_t>(nibble << 4 | v));
      nibble = -1;
    }
  }
  return out;
}

inline CanFrame can_frame(uint32_t id, std::string_view hex_bytes) {
  CanFrame f;
  f.id = id;
  const auto bytes = hex(hex_bytes);
  f.len = static_cast<uint8_t>(bytes.size());
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) f.data[i] = bytes[i];
  return f;
}

// Records everything a reassembler reports.
struct RecordingSink : FrameSink {
  std::vector<AppFrame> frames;
  std::vector<Micros> times;
  std::vector<ReassemblyErrorEvent> errors;
  void on_frame(const AppFrame& f, Micros ts) override {
    frames.push_back(f);
    times.push_back(ts);
  }
  void on_error(const ReassemblyErrorEvent& e) override { errors.push_back(e); }
};

}  // namespace motinova::test
