// `fleetgw decode [FILE|-]`: reads a candump -L log, reassembles and decodes it, writes one JSON
// object per valid application frame to `out`, and a summary of every error to `err`.
//
// Contract: frames that fail CRC or framing are never printed as messages; with
// `print_errors`, each reassembly error and each malformed log line becomes a JSON line of its
// own ({"error": ...}). The exit status is 0 when at least one message decoded (errors in the
// data are data, not a failure of the tool), 1 when nothing decoded (garbage, a binary file,
// every CRC failing: the error output then says what to try, e.g. --crc-order auto), 2 when the
// file could not be opened.
#pragma once

#include <iosfwd>
#include <string>

#include "motinova/options.h"
#include "motinova/reassembler.h"

namespace fleetgw::decode {

struct DecodeCommandOptions {
  std::string input = "-";  // file, or "-" for standard input
  bool print_errors = false;
  motinova::DecodeOptions protocol;
  motinova::Micros gap_timeout{100'000};
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

}  // namespace fleetgw::decode
