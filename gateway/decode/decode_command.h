// `fleetgw decode [FILE|-]`: reads a candump -L log, reassembles and decodes it, writes one JSON
// object per valid application frame to `out`, and a summary of every error to `err`.
//
// Contract: frames that fail CRC or framing are never printed as messages; with
// `print_errors`, each reassembly error and each malformed log line becomes a JSON line of its
// own ({"error": ...}). The exit status is 0 when at least one message decoded (errors in the
// data are data, not a failure of the tool), 1 when nothing decoded (garbage, a binary file,
// every CRC failing: the error output then says what to try, e.g. --crc-order auto), 2 when the
// file could not be opened.
//
// The summary on `err` takes `summary_format` (`fleetgw decode --format`): table (the default,
// for people) is the one line of format_summary() followed, when nothing decoded, by one
// "decode: ..." line with the hint; json is one line holding summary_document(); csv is that
// document flattened to key,value rows (common::flatten, RFC 4180). With json or csv, `err`
// carries the summary alone: malformed log lines are counted in it, not reported one by one
// (--errors still lists them on `out`), and the hint is its "hint" member. The JSON lines of
// the decoded messages on `out` are the same in every format.
#pragma once

#include <nlohmann/json.hpp>

#include <iosfwd>
#include <string>

#include "gateway/common/table_format.h"
#include "motinova/options.h"
#include "motinova/reassembler.h"

namespace fleetgw::decode {

struct DecodeCommandOptions {
  std::string input = "-";  // file, or "-" for standard input
  bool print_errors = false;
  motinova::DecodeOptions protocol;
  motinova::Micros gap_timeout{100'000};
  common::OutputFormat summary_format = common::OutputFormat::kTable;
};

struct DecodeSummary {
  uint64_t lines_malformed = 0;
  uint64_t non_data_frames = 0;  // remote, error and extended frames: not MOTINOVA traffic
  uint64_t messages = 0;
  uint64_t unknown_messages = 0;
  motinova::ReassemblerStats reassembly;
};

int run_decode(const DecodeCommandOptions& options, std::ostream& out, std::ostream& err,
               DecodeSummary* summary = nullptr);

// Human-readable summary ("decode: 812 CAN frames, 140 messages (2 unknown); errors: ...").
std::string format_summary(const DecodeSummary& s);

// The summary for scripts. Every key is always present, so a script sees the same keys on every
// run: can_frames, messages, unknown_messages, non_data_frames, malformed_lines, frame_errors
// (one member per reassembly error kind, e.g. bad_crc, 0 included), crc_order_seen {be, le}
// (valid frames per CRC byte order). run_decode adds input (the file, or "stdin") and hint (what
// to try when nothing decoded, otherwise null).
nlohmann::json summary_document(const DecodeSummary& s);

}  // namespace fleetgw::decode
