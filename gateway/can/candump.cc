#include "gateway/can/candump.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <istream>
#include <stdexcept>
#include <streambuf>
#include <utility>

namespace fleetgw::can::candump {
namespace {

// Linux IFNAMSIZ is 16 including the terminating NUL.
constexpr std::size_t kMaxInterfaceName = 15;
// Seconds with more digits than this would overflow the microsecond count; real logs have 10.
constexpr std::size_t kMaxSecondsDigits = 12;
// LineReader's buffer holds one block plus the start of a line cut by the block's end.
constexpr std::size_t kReadBlock = 64 * 1024;

constexpr int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// hex_value() as a table, for the fast path.
constexpr std::array<int8_t, 256> kHexDigit = [] {
  std::array<int8_t, 256> t{};
  for (auto& v : t) v = -1;
  for (int c = 0; c < 256; ++c)
    t[static_cast<std::size_t>(c)] = static_cast<int8_t>(hex_value(static_cast<char>(c)));
  return t;
}();

int hex_digit(char c) {
  return kHexDigit[static_cast<unsigned char>(c)];
}

// The exact shape candump -L writes, "(1763700000.123456) can0 710#55AA0C22": a standard data
// frame, 6-digit microseconds, single spaces, nothing after the payload. Such a line is parsed
// here in one pass without the general parser's bookkeeping (the general parser was a fifth of
// a replay's CPU). Anything else -- every error included -- returns false and goes through the
// general parser, so the error messages stay the same.
bool parse_canonical(std::string_view line, LogRecord& rec) {
  const char* p = line.data();
  const char* const end = p + line.size();
  if (line.size() < 16 || *p != '(') return false;
  ++p;
  const char* const sec_begin = p;
  int64_t seconds = 0;
  while (p < end && static_cast<unsigned>(*p - '0') < 10) seconds = seconds * 10 + (*p++ - '0');
  if (p == sec_begin || static_cast<std::size_t>(p - sec_begin) > kMaxSecondsDigits ||
      end - p < 9 || *p != '.') {
    return false;
  }
  ++p;
  int64_t micros = 0;
  for (int i = 0; i < 6; ++i) {
    const unsigned d = static_cast<unsigned>(p[i] - '0');
    if (d > 9) return false;
    micros = micros * 10 + d;
  }
  p += 6;
  if (p[0] != ')' || p[1] != ' ') return false;
  p += 2;
  const char* const if_begin = p;
  while (p < end && *p != ' ' && *p != '\t') ++p;
  const auto if_len = static_cast<std::size_t>(p - if_begin);
  if (if_len == 0 || if_len > kMaxInterfaceName || end - p < 5 || *p != ' ') return false;
  ++p;
  if (p[3] != '#') return false;
  const int h0 = hex_digit(p[0]), h1 = hex_digit(p[1]), h2 = hex_digit(p[2]);
  if ((h0 | h1 | h2) < 0 || h0 > 7) return false;
  p += 4;
  const auto hex_len = static_cast<std::size_t>(end - p);
  if (hex_len % 2 != 0 || hex_len > 16) return false;
  motinova::CanFrame frame;
  frame.id = static_cast<uint32_t>((h0 << 8) | (h1 << 4) | h2);
  frame.len = static_cast<uint8_t>(hex_len / 2);
  for (std::size_t i = 0; i < frame.len; ++i) {
    const int hi = hex_digit(p[2 * i]);
    const int lo = hex_digit(p[2 * i + 1]);
    if ((hi | lo) < 0) return false;
    frame.data[i] = static_cast<uint8_t>((hi << 4) | lo);
  }
  rec.timestamp = motinova::Micros{seconds * 1'000'000 + micros};
  rec.interface.assign(if_begin, if_len);
  rec.frame = frame;
  rec.kind = FrameKind::kData;
  rec.extended = false;
  return true;
}

bool is_space(char c) {
  return c == ' ' || c == '\t';
}

std::string printable(char c) {
  if (c >= 0x20 && c < 0x7F) return std::string("'") + c + "'";
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02X", static_cast<unsigned char>(c));
  return buf;
}

// Carries the line being parsed so every error names line and column the same way.
class Parser {
 public:
  Parser(std::string_view line, std::size_t line_no) : line_(line), line_no_(line_no) {}

  ParseResult run();

 private:
  ParseResult fail(std::size_t pos, std::string what, bool unsupported = false) const {
    ParseError e;
    e.line = line_no_;
    e.column = pos + 1;
    e.unsupported = unsupported;
    e.message = "line " + std::to_string(line_no_) + ", column " + std::to_string(pos + 1) + ": " +
                std::move(what);
    return ParseResult{std::nullopt, std::move(e)};
  }
  bool at_end() const { return pos_ >= line_.size(); }
  char peek() const { return at_end() ? '\0' : line_[pos_]; }
  void skip_spaces() {
    while (!at_end() && is_space(line_[pos_])) ++pos_;
  }
  std::string_view token() {
    const std::size_t start = pos_;
    while (!at_end() && !is_space(line_[pos_])) ++pos_;
    return line_.substr(start, pos_ - start);
  }

  std::optional<ParseResult> parse_timestamp(LogRecord& rec);
  std::optional<ParseResult> parse_frame(std::string_view tok, std::size_t tok_pos, LogRecord& rec);
  std::optional<ParseResult> parse_payload(std::string_view p, std::size_t p_pos, LogRecord& rec);

  std::string_view line_;
  std::size_t line_no_;
  std::size_t pos_ = 0;
};

ParseResult Parser::run() {
  // Tolerate CRLF files and trailing blanks: they are invisible in an editor.
  while (!line_.empty() && (line_.back() == '\r' || is_space(line_.back()))) line_.remove_suffix(1);
  skip_spaces();
  if (at_end() || peek() == '#') return ParseResult{};  // blank or comment line

  LogRecord rec;
  if (auto err = parse_timestamp(rec)) return std::move(*err);

  if (!at_end() && !is_space(peek())) return fail(pos_, "expected a space after the timestamp");
  skip_spaces();
  if (at_end()) return fail(pos_, "missing interface name after the timestamp");
  const std::size_t if_pos = pos_;
  const std::string_view iface = token();
  if (iface.size() > kMaxInterfaceName) {
    return fail(if_pos, "interface name '" + std::string(iface) + "' is longer than " +
                            std::to_string(kMaxInterfaceName) + " characters");
  }
  rec.interface = std::string(iface);

  skip_spaces();
  if (at_end()) return fail(pos_, "missing frame after interface name '" + rec.interface + "'");
  const std::size_t frame_pos = pos_;
  const std::string_view frame = token();
  if (auto err = parse_frame(frame, frame_pos, rec)) return std::move(*err);

  skip_spaces();
  if (!at_end()) {
    // Newer candump versions may append the direction (R = received, T = transmitted).
    const std::size_t extra_pos = pos_;
    const std::string_view extra = token();
    skip_spaces();
    if (!(extra == "R" || extra == "T") || !at_end()) {
      return fail(extra_pos, "unexpected text '" + std::string(extra) + "' after the frame");
    }
  }
  return ParseResult{std::move(rec), std::nullopt};
}

std::optional<ParseResult> Parser::parse_timestamp(LogRecord& rec) {
  if (peek() != '(') return fail(pos_, "expected '(' opening the timestamp");
  ++pos_;
  const std::size_t sec_pos = pos_;
  int64_t seconds = 0;
  while (!at_end() && peek() >= '0' && peek() <= '9') {
    if (pos_ - sec_pos >= kMaxSecondsDigits) return fail(sec_pos, "timestamp seconds too large");
    seconds = seconds * 10 + (peek() - '0');
    ++pos_;
  }
  if (pos_ == sec_pos) return fail(pos_, "expected digits in the timestamp");
  if (peek() != '.') return fail(pos_, "expected '.' between timestamp seconds and fraction");
  ++pos_;
  const std::size_t frac_pos = pos_;
  int64_t micros = 0;
  std::size_t digits = 0;
  while (!at_end() && peek() >= '0' && peek() <= '9') {
    // Digits beyond microseconds (a nanosecond log) are accepted and truncated.
    if (digits < 6) micros = micros * 10 + (peek() - '0');
    ++digits;
    ++pos_;
  }
  if (digits == 0) return fail(frac_pos, "expected digits after '.' in the timestamp");
  if (digits > 9) return fail(frac_pos, "timestamp fraction has more than 9 digits");
  for (std::size_t i = digits; i < 6; ++i) micros *= 10;
  if (peek() != ')') return fail(pos_, "expected ')' closing the timestamp");
  ++pos_;
  rec.timestamp = motinova::Micros{seconds * 1'000'000 + micros};
  return std::nullopt;
}

std::optional<ParseResult> Parser::parse_frame(std::string_view tok, std::size_t tok_pos,
                                               LogRecord& rec) {
  const std::size_t hash = tok.find('#');
  if (hash == std::string_view::npos) {
    return fail(tok_pos, "missing '#' between CAN ID and payload in '" + std::string(tok) + "'");
  }
  const std::string_view id_text = tok.substr(0, hash);
  if (id_text.size() != 3 && id_text.size() != 8) {
    return fail(tok_pos, "CAN ID '" + std::string(id_text) +
                             "' must have 3 (standard) or 8 (extended) hex digits");
  }
  uint32_t id = 0;
  for (std::size_t i = 0; i < id_text.size(); ++i) {
    const int v = hex_value(id_text[i]);
    if (v < 0)
      return fail(tok_pos + i, "invalid hex digit " + printable(id_text[i]) + " in CAN ID");
    id = (id << 4) | static_cast<uint32_t>(v);
  }
  // Formatted only for an error message: snprintf on every line cost ~7 % of `fleetgw decode`.
  auto hexid = [id] {
    char text[16];
    std::snprintf(text, sizeof text, "0x%X", id);
    return std::string(text);
  };
  if (id_text.size() == 3) {
    if (id > kSffMask) {
      return fail(tok_pos, "standard CAN ID " + hexid() + " exceeds 0x7FF");
    }
    rec.frame.id = id;
  } else if ((id & kErrFlag) != 0) {
    if ((id & (kEffFlag | kRtrFlag)) != 0) {
      return fail(tok_pos, "error frame ID " + hexid() + " also carries EFF/RTR flags");
    }
    rec.kind = FrameKind::kError;
    rec.frame.id = id & kEffMask;
  } else {
    if (id > kEffMask) {
      return fail(tok_pos, "extended CAN ID " + hexid() + " exceeds 29 bits");
    }
    rec.extended = true;
    rec.frame.id = id;
  }

  const std::size_t p_pos = tok_pos + hash + 1;
  const std::string_view payload = tok.substr(hash + 1);
  if (!payload.empty() && payload.front() == '#') {
    return fail(p_pos, "CAN FD frame ('##') is not supported: the MOTINOVA bus is classic CAN",
                /*unsupported=*/true);
  }
  if (!payload.empty() && (payload.front() == 'R' || payload.front() == 'r')) {
    if (rec.kind == FrameKind::kError) return fail(p_pos, "error frame cannot be a remote frame");
    rec.kind = FrameKind::kRemote;
    if (payload.size() == 1) return std::nullopt;
    if (payload.size() == 2 && payload[1] >= '0' && payload[1] <= '8') {
      rec.frame.len = static_cast<uint8_t>(payload[1] - '0');
      return std::nullopt;
    }
    return fail(p_pos + 1, "remote frame DLC must be a single digit 0-8 after 'R'");
  }
  return parse_payload(payload, p_pos, rec);
}

std::optional<ParseResult> Parser::parse_payload(std::string_view p, std::size_t p_pos,
                                                 LogRecord& rec) {
  std::size_t len = 0;
  std::size_t i = 0;
  while (i < p.size()) {
    const char c = p[i];
    if (c == '.') {  // cansend-style byte separator: "11.22.33"
      ++i;
      continue;
    }
    if (c == '_' && len == 8 && i + 2 == p.size() && hex_value(p[i + 1]) >= 9) {
      // Newer candump writes a raw DLC 9..F of an 8-byte frame as "_<dlc>"; the data is what
      // matters to us, the raw DLC is not representable in CanFrame.
      break;
    }
    const int hi = hex_value(c);
    if (hi < 0) return fail(p_pos + i, "invalid character " + printable(c) + " in payload");
    if (i + 1 >= p.size() || p[i + 1] == '.') {
      return fail(p_pos + i, "odd number of hex digits in payload");
    }
    const int lo = hex_value(p[i + 1]);
    if (lo < 0) {
      return fail(p_pos + i + 1, "invalid character " + printable(p[i + 1]) + " in payload");
    }
    if (len == 8) return fail(p_pos + i, "payload longer than 8 bytes (classic CAN)");
    rec.frame.data[len++] = static_cast<uint8_t>((hi << 4) | lo);
    i += 2;
  }
  rec.frame.len = static_cast<uint8_t>(len);
  return std::nullopt;
}

void append_timestamp(std::string& out, motinova::Micros ts) {
  if (ts.count() < 0) throw std::invalid_argument("candump timestamp must not be negative");
  char buf[40];
  std::snprintf(buf, sizeof buf, "(%010lld.%06lld) ",
                static_cast<long long>(ts.count() / 1'000'000),
                static_cast<long long>(ts.count() % 1'000'000));
  out += buf;
}

void append_data(std::string& out, const motinova::CanFrame& f) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (uint8_t i = 0; i < f.len; ++i) {
    out += kHex[f.data[i] >> 4];
    out += kHex[f.data[i] & 0xF];
  }
}

}  // namespace

uint32_t LogRecord::socketcan_id() const {
  switch (kind) {
    case FrameKind::kError:
      return frame.id | kErrFlag;
    case FrameKind::kRemote:
      return frame.id | kRtrFlag | (extended ? kEffFlag : 0);
    case FrameKind::kData:
      break;
  }
  return frame.id | (extended ? kEffFlag : 0);
}

ParseResult parse_line(std::string_view line, std::size_t line_no) {
  ParseResult fast;
  if (parse_canonical(line, fast.record.emplace())) return fast;
  return Parser(line, line_no).run();
}

std::string format_line(motinova::Micros timestamp, std::string_view interface,
                        const motinova::CanFrame& frame) {
  if (frame.id > kSffMask) {
    throw std::invalid_argument("format_line: CAN ID " + std::to_string(frame.id) +
                                " is not an 11-bit identifier");
  }
  LogRecord rec;
  rec.timestamp = timestamp;
  rec.interface = std::string(interface);
  rec.frame = frame;
  return format_record(rec);
}

std::string format_record(const LogRecord& r) {
  if (r.frame.len > 8) {
    throw std::invalid_argument("format_record: CAN frame length " + std::to_string(r.frame.len) +
                                " exceeds 8");
  }
  const uint32_t id_limit = r.extended || r.kind == FrameKind::kError ? kEffMask : kSffMask;
  if (r.frame.id > id_limit) {
    throw std::invalid_argument("format_record: CAN ID " + std::to_string(r.frame.id) +
                                " out of range");
  }
  std::string out;
  out.reserve(64);
  append_timestamp(out, r.timestamp);
  out += r.interface;
  out += ' ';
  char id[16];
  if (r.kind == FrameKind::kError) {
    std::snprintf(id, sizeof id, "%08X#", r.frame.id | kErrFlag);
  } else if (r.extended) {
    std::snprintf(id, sizeof id, "%08X#", r.frame.id);
  } else {
    std::snprintf(id, sizeof id, "%03X#", r.frame.id);
  }
  out += id;
  if (r.kind == FrameKind::kRemote) {
    out += 'R';
    if (r.frame.len > 0) out += static_cast<char>('0' + r.frame.len);
  } else {
    append_data(out, r.frame);
  }
  return out;
}

LineReader::LineReader(std::istream& in, std::size_t max_errors_kept)
    : in_(in), max_errors_kept_(max_errors_kept), buf_(kReadBlock + kMaxLineLength + 1) {}

bool LineReader::fill() {
  if (eof_) return false;
  std::streambuf* sb = in_.rdbuf();
  // sgetc() waits for input only when the stream's buffer is empty (one read() for a file or a
  // pipe); in_avail() then tells how much can be taken without waiting again.
  if (sb == nullptr || sb->sgetc() == std::char_traits<char>::eof()) {
    eof_ = true;
    return false;
  }
  if (begin_ > 0) {  // keep the unfinished line at the front: the room is at the end
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  const auto room = static_cast<std::streamsize>(buf_.size() - end_);
  const std::streamsize want = std::clamp<std::streamsize>(sb->in_avail(), 1, room);
  const std::streamsize got = sb->sgetn(buf_.data() + end_, want);
  if (got <= 0) {
    eof_ = true;
    return false;
  }
  end_ += static_cast<std::size_t>(got);
  return true;
}

bool LineReader::read_line(std::string_view& line, bool& too_long) {
  for (;;) {
    const char* base = buf_.data();
    const auto* nl = static_cast<const char*>(
        std::memchr(base + begin_ + scanned_, '\n', end_ - begin_ - scanned_));
    if (nl != nullptr) {
      const auto len = static_cast<std::size_t>(nl - (base + begin_));
      too_long = skipping_ || len > kMaxLineLength;
      line = too_long ? std::string_view() : std::string_view(base + begin_, len);
      begin_ += len + 1;
      scanned_ = 0;
      skipping_ = false;
      return true;
    }
    scanned_ = end_ - begin_;
    if (scanned_ > kMaxLineLength) {  // drop the overlong line's bytes instead of keeping them
      skipping_ = true;
      begin_ = end_ = scanned_ = 0;
    }
    if (!fill()) {
      if (begin_ == end_ && !skipping_) return false;
      // The last line has no '\n'.
      too_long = skipping_;
      line = too_long ? std::string_view() : std::string_view(base + begin_, end_ - begin_);
      begin_ = end_ = scanned_ = 0;
      skipping_ = false;
      return true;
    }
  }
}

void LineReader::report(ParseError error) {
  ++error_count_;
  if (on_error_) on_error_(error);
  if (errors_.size() < max_errors_kept_) errors_.push_back(std::move(error));
}

std::optional<LogRecord> LineReader::next() {
  bool too_long = false;
  std::string_view line;
  while (read_line(line, too_long)) {
    ++line_no_;
    if (too_long) {
      ParseError e;
      e.line = line_no_;
      e.message = "line " + std::to_string(line_no_) + ": line longer than " +
                  std::to_string(kMaxLineLength) + " characters";
      report(std::move(e));
      continue;
    }
    ParseResult r = parse_line(line, line_no_);
    if (r.error) {
      report(std::move(*r.error));
      continue;
    }
    if (r.record) return std::move(r.record);
  }
  return std::nullopt;
}

}  // namespace fleetgw::can::candump
