// Reader and writer for the can-utils `candump -L` log format, the interchange format of fleetgw
// recordings (replay transport, decode tool, test fixtures):
//
//   (1763700000.123456) can0 710#55AA0C22
//
// Contract:
//  * parse_line() never throws on data: it returns either a LogRecord, an error naming the line,
//    the column and what is wrong ("line 17, column 31: odd number of hex digits in payload"), or
//    neither for a blank line or a `#` comment line.
//  * Accepted frame notations: standard data frames `7FF#0011..` (3 hex digits, up to 8 data
//    bytes, bytes optionally separated by '.'), extended IDs (8 hex digits), remote frames `R`
//    with an optional DLC digit (`710#R`, `710#R4`), and error frames (8-digit ID carrying
//    CAN_ERR_FLAG 0x20000000). CAN FD lines (`##`) are recognised and reported as an
//    "unsupported" error, since the MOTINOVA bus is classic CAN.
//  * An optional trailing direction token (`R` / `T`, as newer candump versions write) is
//    accepted and ignored.
//  * format_line()/format_record() write exactly what candump -L writes (upper-case hex,
//    6-digit microseconds), so a parse/format round trip reproduces the line byte for byte.
//  * LineReader streams records from an std::istream, skipping malformed lines and collecting
//    their errors, so one bad line in a day-long recording costs one line, not the file. Lines are
//    bounded (kMaxLineLength); a longer line is reported and skipped without buffering it whole.
//    It reads in blocks of what the stream has buffered (never waiting for a full block, so a
//    live pipe is read as data arrives) and parses each line in place: no copy, no allocation
//    per line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "motinova/can.h"

namespace fleetgw::can::candump {

// SocketCAN flag bits as they appear in candump's 8-digit IDs (same values as <linux/can.h>,
// repeated here so this header stays free of Linux headers).
inline constexpr uint32_t kEffFlag = 0x80000000U;
inline constexpr uint32_t kRtrFlag = 0x40000000U;
inline constexpr uint32_t kErrFlag = 0x20000000U;
inline constexpr uint32_t kSffMask = 0x000007FFU;
inline constexpr uint32_t kEffMask = 0x1FFFFFFFU;

inline constexpr std::size_t kMaxLineLength = 4096;

enum class FrameKind : uint8_t {
  kData,    // ordinary data frame
  kRemote,  // RTR frame: frame.len is the requested DLC, data is all zero
  kError,   // error frame: frame.id holds the error class bits (without CAN_ERR_FLAG)
};

struct LogRecord {
  motinova::Micros timestamp{0};  // microseconds since the Unix epoch, as recorded
  std::string interface;          // "can0", "vcan0", ...
  motinova::CanFrame frame;       // id without flag bits: 11 bits, or 29 bits when extended
  FrameKind kind = FrameKind::kData;
  bool extended = false;  // written with an 8-digit ID (29-bit identifier)

  // The SocketCAN can_id: identifier plus EFF/RTR/ERR flags.
  uint32_t socketcan_id() const;
  // A standard (11-bit) data frame: the only kind the MOTINOVA bus uses.
  bool is_standard_data() const { return kind == FrameKind::kData && !extended; }
  friend bool operator==(const LogRecord&, const LogRecord&) = default;
};

struct ParseError {
  std::size_t line = 0;
  std::size_t column = 0;    // 1-based; 0 when the error is about the whole line
  bool unsupported = false;  // well-formed but not something classic CAN carries (CAN FD)
  std::string message;       // complete text, "line 17, column 31: ..."
};

struct ParseResult {
  std::optional<LogRecord> record;  // set on success
  std::optional<ParseError> error;  // set on failure
  // Neither set: blank or comment line.
  bool ok() const { return !error.has_value(); }
};

ParseResult parse_line(std::string_view line, std::size_t line_no);

// Writes a standard data frame. Throws std::invalid_argument for a negative timestamp, an ID
// above 0x7FF or a length above 8: those are programming errors, not data errors.
std::string format_line(motinova::Micros timestamp, std::string_view interface,
                        const motinova::CanFrame& frame);
// Writes any record parse_line() can return (remote, error, extended frames included).
std::string format_record(const LogRecord& record);

class LineReader {
 public:
  using ErrorHandler = std::function<void(const ParseError&)>;

  // `in` must outlive the reader. At most `max_errors_kept` errors are stored (the count keeps
  // going), so a garbage file cannot exhaust memory.
  explicit LineReader(std::istream& in, std::size_t max_errors_kept = 1000);

  // Called for every malformed line as it is met (e.g. to log it), in addition to errors().
  void on_error(ErrorHandler handler) { on_error_ = std::move(handler); }

  // Next well-formed record, or nullopt at end of input.
  std::optional<LogRecord> next();

  const std::vector<ParseError>& errors() const { return errors_; }
  std::size_t error_count() const { return error_count_; }
  std::size_t line_number() const { return line_no_; }  // last line read

 private:
  // Next line (without its '\n') as a view into buf_, valid until the next call; false at end of
  // input. Sets too_long (and an empty line) for a line over kMaxLineLength.
  bool read_line(std::string_view& line, bool& too_long);
  // Appends what the stream has available (at least one byte, waiting for it) to buf_; false at
  // end of input.
  bool fill();
  void report(ParseError error);

  std::istream& in_;
  std::size_t max_errors_kept_;
  std::vector<char> buf_;  // bytes [begin_, end_) read but not yet consumed
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  std::size_t scanned_ = 0;  // bytes after begin_ known to hold no '\n'
  bool skipping_ = false;    // inside an overlong line: its bytes are dropped as they come
  bool eof_ = false;
  std::size_t line_no_ = 0;
  std::size_t error_count_ = 0;
  std::vector<ParseError> errors_;
  ErrorHandler on_error_;
};

}  // namespace fleetgw::can::candump
