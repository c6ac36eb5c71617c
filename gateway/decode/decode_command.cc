#include "gateway/decode/decode_command.h"

#include <fmt/format.h>

#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "gateway/can/candump.h"
#include "gateway/decode/json_format.h"
#include "motinova/codec.h"

namespace fleetgw::decode {
namespace {

// Output is assembled in one reused buffer and handed to the stream in large blocks: no JSON
// tree and no stream formatting per message.
class JsonLinesSink : public motinova::FrameSink {
 public:
  JsonLinesSink(const DecodeCommandOptions& options, std::ostream& out, DecodeSummary& summary)
      : options_(options), out_(out), summary_(summary) {}
  ~JsonLinesSink() override { flush(); }
  JsonLinesSink(const JsonLinesSink&) = delete;
  JsonLinesSink& operator=(const JsonLinesSink&) = delete;

  void on_frame(const motinova::AppFrame& frame, motinova::Micros ts) override {
    motinova::decode(frame, motinova::Catalogue::standard(), options_.protocol, decoded_);
    ++summary_.messages;
    if (!decoded_.desc) ++summary_.unknown_messages;
    append_message_json(buffer_, decoded_, ts, options_.protocol);
    end_line();
  }
  void on_error(const motinova::ReassemblyErrorEvent& e) override {
    if (!options_.print_errors) return;
    append_error_json(buffer_, e);
    end_line();
  }
  void malformed_line(std::size_t line, std::string_view message) {
    buffer_ += "{\"error\":\"malformed_line\",\"line\":";
    buffer_ += std::to_string(line);
    buffer_ += ",\"message\":";
    append_json_string(buffer_, message);
    buffer_ += '}';
    end_line();
  }
  void flush() {
    out_.write(buffer_.view().data(), static_cast<std::streamsize>(buffer_.size()));
    buffer_.clear();
    if (flush_stream_) {
      out_.flush();
      flush_stream_ = false;
    }
  }
  // Live input: hand what was decoded so far on before waiting for more input.
  void flush_soon() {
    flush_stream_ = true;
    flush();
  }

 private:
  static constexpr std::size_t kFlushBytes = 64 * 1024;
  void end_line() {
    buffer_ += '\n';
    if (buffer_.size() >= kFlushBytes) flush();
  }

  const DecodeCommandOptions& options_;
  std::ostream& out_;
  DecodeSummary& summary_;
  motinova::DecodedMessage decoded_;
  JsonBuffer buffer_;
  bool flush_stream_ = false;
};

// Splits the input into lines, reading 64 KiB blocks: reading the stream one character at a
// time (candump::LineReader) was a third of the decode time on a 1-hour log. Lines longer than
// candump::kMaxLineLength are reported as too long without being stored whole, as LineReader does.
// `read_some(buffer, size)` returns the bytes read, 0 at the end of the input.
template <typename ReadSome, typename OnLine>
void for_each_line(ReadSome&& read_some, OnLine&& on_line) {
  constexpr std::size_t kBlock = 64 * 1024;
  std::vector<char> block(kBlock);
  std::string carry;  // the start of a line cut by the end of a block
  bool too_long = false;
  std::size_t line_no = 0;
  auto keep = [&](std::string_view part) {
    const std::size_t room = can::candump::kMaxLineLength - carry.size();
    if (part.size() > room) too_long = true;
    carry.append(part.substr(0, std::min(room, part.size())));
  };
  for (std::size_t got; (got = read_some(block.data(), kBlock)) > 0;) {
    std::string_view chunk(block.data(), got);
    while (!chunk.empty()) {
      const std::size_t nl = chunk.find('\n');
      if (nl == std::string_view::npos) {
        keep(chunk);
        break;
      }
      std::string_view line = chunk.substr(0, nl);
      if (!carry.empty() || too_long) {
        keep(line);
        line = carry;
      } else if (line.size() > can::candump::kMaxLineLength) {
        too_long = true;
      }
      on_line(line, ++line_no, too_long);
      carry.clear();
      too_long = false;
      chunk.remove_prefix(nl + 1);
    }
  }
  if (!carry.empty() || too_long) on_line(std::string_view(carry), ++line_no, too_long);
}

std::string nothing_decoded_hint(const DecodeSummary& s, const DecodeCommandOptions& options) {
  const auto& r = s.reassembly;
  if (r.can_frames == 0) {
    return s.lines_malformed > 0
               ? "no candump -L line in the input (expected lines such as "
                 "\"(1700000000.000000) can0 710#55AA0C...\"; record with candump -L)"
               : "the input holds no CAN frame";
  }
  std::string hint = "no valid MOTINOVA message in the input";
  if (r.error(motinova::ReassemblyError::kBadCrc) > 0 &&
      options.protocol.crc_order != motinova::CrcOrder::kAuto) {
    hint += "; every complete frame failed its CRC: try --crc-order auto (spec U1)";
  } else if (r.error(motinova::ReassemblyError::kForeignId) == r.can_frames) {
    hint += "; no frame on the MOTINOVA IDs 0x700-0x7FF";
  } else {
    hint += "; check that the log is from a MOTINOVA bus (try --errors to see why frames fail)";
  }
  return hint;
}

void print_summary(const DecodeCommandOptions& options, const DecodeSummary& summary,
                   const std::string& source, const std::string& hint, std::ostream& err) {
  if (options.summary_format == common::OutputFormat::kTable) {
    err << format_summary(summary) << '\n';
    if (!hint.empty()) err << "decode: " << hint << '\n';
    return;
  }
  nlohmann::json doc = summary_document(summary);
  doc["input"] = source;
  doc["hint"] = hint.empty() ? nlohmann::json() : nlohmann::json(hint);
  if (options.summary_format == common::OutputFormat::kJson) {
    // A file name is bytes, not necessarily UTF-8: replaced, never an exception.
    err << doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
  } else {
    common::write_as(options.summary_format, common::flatten(doc), err);
  }
}

}  // namespace

nlohmann::json summary_document(const DecodeSummary& s) {
  nlohmann::json errors = nlohmann::json::object();
  for (std::size_t k = 0; k < motinova::kReassemblyErrorKinds; ++k) {
    errors[std::string(motinova::reassembly_error_name(
        static_cast<motinova::ReassemblyError>(k)))] = s.reassembly.errors[k];
  }
  return {{"can_frames", s.reassembly.can_frames},
          {"messages", s.messages},
          {"unknown_messages", s.unknown_messages},
          {"non_data_frames", s.non_data_frames},
          {"malformed_lines", s.lines_malformed},
          {"frame_errors", std::move(errors)},
          {"crc_order_seen",
           {{"be", s.reassembly.crc_big_endian}, {"le", s.reassembly.crc_little_endian}}}};
}

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
  const std::string source = options.input == "-" ? "stdin" : options.input;
  // A binary or foreign file would print one message per line: report the first few only.
  constexpr uint64_t kMaxReportedLines = 20;
  uint64_t malformed = 0;
  // json and csv: the summary is all that goes to `err`, so a script can parse it.
  const bool report_lines = options.summary_format == common::OutputFormat::kTable;
  auto report = [&](const can::candump::ParseError& e) {
    if (!report_lines) {
      ++malformed;
    } else if (++malformed <= kMaxReportedLines) {
      err << source << ": " << e.message << '\n';
    } else if (malformed == kMaxReportedLines + 1) {
      err << source << ": more malformed lines are counted, not shown\n";
    }
    if (options.print_errors) sink.malformed_line(e.line, e.message);
  };
  // A file is read in full blocks; standard input may be a live `candump -L can0 |` pipe, so it
  // is read as data arrives and the output is flushed after each read.
  const bool live = options.input == "-";
  auto read_some = [&](char* buffer, std::size_t size) -> std::size_t {
    if (live) {
      sink.flush_soon();  // before waiting for input that may take a while to come
      for (;;) {
        const ssize_t n = ::read(STDIN_FILENO, buffer, size);
        if (n >= 0) return static_cast<std::size_t>(n);
        if (errno != EINTR) return 0;
      }
    }
    in->read(buffer, static_cast<std::streamsize>(size));
    return static_cast<std::size_t>(in->gcount());
  };
  motinova::Micros last{0};
  for_each_line(read_some, [&](std::string_view line, std::size_t line_no, bool too_long) {
    if (too_long) {
      can::candump::ParseError e;
      e.line = line_no;
      e.message = "line " + std::to_string(line_no) + ": line longer than " +
                  std::to_string(can::candump::kMaxLineLength) + " characters";
      report(e);
      return;
    }
    const can::candump::ParseResult parsed = can::candump::parse_line(line, line_no);
    if (parsed.error) {
      report(*parsed.error);
      return;
    }
    if (!parsed.record) return;  // blank or comment line
    const auto& record = *parsed.record;
    if (!record.is_standard_data()) {  // remote/error/extended frames: not MOTINOVA traffic
      ++summary.non_data_frames;
      return;
    }
    last = record.timestamp;
    reassembler.push(record.frame, record.timestamp, sink);
  });
  // Whatever is still partial at the end of the log is reported, not silently dropped.
  reassembler.expire(last + options.gap_timeout + motinova::Micros(1), sink);
  sink.flush();
  out.flush();
  summary.lines_malformed = malformed;
  summary.reassembly = reassembler.stats();
  const std::string hint = summary.messages == 0 ? nothing_decoded_hint(summary, options) : "";
  print_summary(options, summary, source, hint, err);
  if (summary_out) *summary_out = summary;
  return summary.messages == 0 ? 1 : 0;
}

}  // namespace fleetgw::decode
