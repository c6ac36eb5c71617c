#include "gateway/decode/decode_command.h"

#include <fmt/format.h>

#include <fstream>
#include <iostream>

#include "gateway/can/candump.h"
#include "gateway/decode/json_format.h"
#include "motinova/codec.h"

namespace fleetgw::decode {
namespace {

class JsonLinesSink : public motinova::FrameSink {
 public:
  JsonLinesSink(const DecodeCommandOptions& options, std::ostream& out, DecodeSummary& summary)
      : options_(options), out_(out), summary_(summary) {}

  void on_frame(const motinova::AppFrame& frame, motinova::Micros ts) override {
    motinova::decode(frame, motinova::Catalogue::standard(), options_.protocol, decoded_);
    ++summary_.messages;
    if (!decoded_.desc) ++summary_.unknown_messages;
    out_ << message_to_json(decoded_, ts, options_.protocol).dump() << '\n';
  }
  void on_error(const motinova::ReassemblyErrorEvent& e) override {
    if (options_.print_errors) out_ << error_to_json(e).dump() << '\n';
  }

 private:
  const DecodeCommandOptions& options_;
  std::ostream& out_;
  DecodeSummary& summary_;
  motinova::DecodedMessage decoded_;
};

}  // namespace

std::string format_summary(const DecodeSummary& s) {
  std::string text = fmt::format("decode: {} CAN frames, {} messages ({} unknown)",
                                 s.reassembly.can_frames, s.messages, s.unknown_messages);
  std::string errors;
  for (std::size_t k = 0; k < motinova::kReassemblyErrorKinds; ++k) {
    if (s.reassembly.errors[k] == 0) continue;
    errors += fmt::format(
        " {}={}", motinova::reassembly_error_name(static_cast<motinova::ReassemblyError>(k)),
        s.reassembly.errors[k]);
  }
  text += errors.empty() ? "; no frame errors" : "; frame errors:" + errors;
  if (s.non_data_frames) {
    text += fmt::format("; {} remote/error/extended frames skipped", s.non_data_frames);
  }
  if (s.lines_malformed) text += fmt::format("; {} malformed log lines", s.lines_malformed);
  if (s.reassembly.crc_little_endian && s.reassembly.crc_big_endian) {
    text += fmt::format("; CRC order seen: {} be, {} le", s.reassembly.crc_big_endian,
                        s.reassembly.crc_little_endian);
  } else if (s.reassembly.crc_little_endian) {
    text += "; CRC order seen: little-endian";
  }
  return text;
}

int run_decode(const DecodeCommandOptions& options, std::ostream& out, std::ostream& err,
               DecodeSummary* summary_out) {
  std::ifstream file;
  std::istream* in = &std::cin;
  if (options.input != "-") {
    file.open(options.input, std::ios::binary);
    if (!file) {
      err << "decode: cannot open " << options.input << '\n';
      return 2;
    }
    in = &file;
  }
  DecodeSummary summary;
  motinova::Reassembler reassembler(motinova::ReassemblerOptions{
      .gap_timeout = options.gap_timeout, .crc_order = options.protocol.crc_order});
  JsonLinesSink sink(options, out, summary);
  can::candump::LineReader reader(*in);
  const std::string source = options.input == "-" ? "stdin" : options.input;
  reader.on_error([&](const can::candump::ParseError& e) {
    err << source << ": " << e.message << '\n';
    if (options.print_errors) {
      out << nlohmann::ordered_json{{"error", "malformed_line"},
                                    {"line", e.line},
                                    {"message", e.message}}
                 .dump()
          << '\n';
    }
  });
  motinova::Micros last{0};
  while (auto record = reader.next()) {
    if (!record->is_standard_data()) {  // remote/error/extended frames: not MOTINOVA traffic
      ++summary.non_data_frames;
      continue;
    }
    last = record->timestamp;
    reassembler.push(record->frame, record->timestamp, sink);
  }
  // Whatever is still partial at the end of the log is reported, not silently dropped.
  reassembler.expire(last + options.gap_timeout + motinova::Micros(1), sink);
  summary.lines_malformed = reader.error_count();
  summary.reassembly = reassembler.stats();
  err << format_summary(summary) << '\n';
  if (summary_out) *summary_out = summary;
  return 0;
}

}  // namespace fleetgw::decode
