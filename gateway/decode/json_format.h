// JSON rendering of decoded MOTINOVA messages and reassembly errors: the output format of
// `fleetgw decode` (one object per line) and of anything else that shows bus traffic.
//
// Contract: the append_* functions write one compact JSON object (no newline) at the end of
// `out` without building an intermediate JSON tree: once the buffer has grown, nothing is
// allocated per message. Output is valid JSON: strings are escaped (", \, control characters),
// and bytes outside ASCII, which only untrusted bus text can carry, are written as \u00XX.
// Field names are the product vocabulary of the catalogue; values are scaled to the unit in
// their name; invalid values (the spec's 0xFF/0xFFFF sentinels) are null. Numbers are printed as
// nlohmann::json prints them (integers plain, doubles shortest round-trip with ".0" when whole).
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>

#include "motinova/codec.h"
#include "motinova/options.h"
#include "motinova/reassembler.h"

namespace fleetgw::decode {

// A growable character buffer whose appends are inline: std::string's appends are out-of-line
// calls, and they were most of the time spent writing JSON. Only the operations the writer needs.
class JsonBuffer {
 public:
  JsonBuffer() = default;
  JsonBuffer(const JsonBuffer&) = delete;
  JsonBuffer& operator=(const JsonBuffer&) = delete;

  JsonBuffer& operator+=(char c) {
    reserve(1);
    *end_++ = c;
    return *this;
  }
  JsonBuffer& operator+=(std::string_view s) {
    append(s.data(), s.size());
    return *this;
  }
  JsonBuffer& operator+=(const char* s) { return *this += std::string_view(s); }
  void append(const char* s, std::size_t n) {
    reserve(n);
    if (n > 0) std::memcpy(end_, s, n);
    end_ += n;
  }
  void append(std::size_t n, char c) {
    reserve(n);
    std::memset(end_, c, n);
    end_ += n;
  }
  std::string_view view() const { return {data_.get(), size()}; }
  std::size_t size() const { return static_cast<std::size_t>(end_ - data_.get()); }
  void clear() { end_ = data_.get(); }

 private:
  void reserve(std::size_t n) {
    if (static_cast<std::size_t>(cap_ - end_) < n) grow(n);
  }
  void grow(std::size_t n);

  std::unique_ptr<char[]> data_;
  char* end_ = nullptr;
  char* cap_ = nullptr;
};

// {"ts", "can_id", "src", "dst", "mode", "function", "message", ["mode_mismatch",] "fields"}.
void append_message_json(JsonBuffer& out, const motinova::DecodedMessage& message,
                         motinova::Micros ts, const motinova::DecodeOptions& options);

// Only the "fields" object.
void append_fields_json(JsonBuffer& out, const motinova::DecodedMessage& message,
                        const motinova::DecodeOptions& options);

// {"ts", "can_id", "error", "bytes_dropped"}.
void append_error_json(JsonBuffer& out, const motinova::ReassemblyErrorEvent& error);

// A JSON string literal (with quotes) of untrusted text.
void append_json_string(JsonBuffer& out, std::string_view text);

// A double as nlohmann::json dumps it ("25.3", "1700000000.0", "1e-05").
void append_json_double(JsonBuffer& out, double value);

// Lock kind fitted at a lock node per options (U21), or "" when `node` is not a lock.
std::string lock_kind(motinova::Node node, const motinova::DecodeOptions& options);

// "0x710"-style hex.
std::string hex_id(uint32_t value, int digits = 3);

}  // namespace fleetgw::decode
