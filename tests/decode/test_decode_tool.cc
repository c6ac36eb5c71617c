// `fleetgw decode`: candump -L in, one JSON object per valid application frame out, with the
// product's field vocabulary; bad input counted and reported, never printed as a message.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <unistd.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "gateway/can/candump.h"
#include "gateway/decode/decode_command.h"
#include "gateway/decode/json_format.h"
#include "motinova/codec.h"
#include "motinova/segmenter.h"

namespace fleetgw::decode {
namespace {

using nlohmann::json;

// Spec §2.5 decoder vectors, as the bus carries them.
const char* kMcStatus =
    "55AA0C22102000FD0BB800FABB801450461E0002F150004104D20C4B5550007B07080000000050B77AEDF0";
const char* kLockStatus = "55AA0C1210102EE000964102000100000000000000003C3501BDF0";

std::vector<uint8_t> bytes(std::string_view hex) {
  std::vector<uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<uint8_t>(std::stoi(std::string(hex.substr(i, 2)), nullptr, 16)));
  }
  return out;
}

std::string log_of(uint16_t id, std::string_view frame_hex, int64_t start_us) {
  std::string log;
  int64_t t = start_us;
  for (const auto& can : motinova::segment(id, bytes(frame_hex))) {
    log += can::candump::format_line(motinova::Micros(t), "can0", can) + "\n";
    t += 100;
  }
  return log;
}

struct Run {
  std::vector<json> lines;
  std::string err;
  DecodeSummary summary;
  int exit_code = 0;
};

Run decode_text(const std::string& text, bool errors = false,
                motinova::DecodeOptions protocol = {}) {
  // One file per test: CTest runs the tests of this binary in parallel processes.
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const auto path =
      testing::TempDir() + "/decode_" + info->name() + "_" + std::to_string(::getpid()) + ".log";
  std::ofstream(path) << text;
  DecodeCommandOptions o;
  o.input = path;
  o.print_errors = errors;
  o.protocol = std::move(protocol);
  std::ostringstream out, err;
  Run r;
  r.exit_code = run_decode(o, out, err, &r.summary);
  std::istringstream lines(out.str());
  for (std::string line; std::getline(lines, line);) r.lines.push_back(json::parse(line));
  r.err = err.str();
  return r;
}

TEST(DecodeTool, McRunningDataVectorGivesTheProductFields) {
  const auto r = decode_text(log_of(0x710, kMcStatus, 1763700000123456));
  EXPECT_EQ(r.exit_code, 0);
  ASSERT_EQ(r.lines.size(), 1u);
  const json& m = r.lines[0];
  EXPECT_EQ(m["can_id"], "0x710");
  EXPECT_EQ(m["src"], "mc");
  EXPECT_EQ(m["dst"], "all");
  EXPECT_EQ(m["mode"], "report");
  EXPECT_EQ(m["function"], "0x10");
  EXPECT_EQ(m["message"], "mc_status");
  EXPECT_NEAR(m["ts"].get<double>(), 1763700000.123956, 1e-6);  // time of the last segment
  const json& f = m["fields"];
  EXPECT_DOUBLE_EQ(f["speed_kmh"].get<double>(), 25.3);
  EXPECT_EQ(f["motor_rpm"], 3000);
  EXPECT_EQ(f["power_w"], 250);
  EXPECT_DOUBLE_EQ(f["voltage_v"].get<double>(), 48.0);
  EXPECT_DOUBLE_EQ(f["current_a"].get<double>(), 5.2);
  EXPECT_EQ(f["cadence_rpm"], 70);
  EXPECT_EQ(f["torque_nm"], 30);
  EXPECT_EQ(f["assist"], 2);
  EXPECT_EQ(f["assist_name"], "norm");
  EXPECT_EQ(f["headlight"], true);
  EXPECT_EQ(f["soc_pct"], 80);
  EXPECT_EQ(f["range_km"], 65);
  EXPECT_EQ(f["odo_km"], 1234);
  EXPECT_DOUBLE_EQ(f["consumption_ah_per_km"].get<double>(), 0.12);
  EXPECT_EQ(f["pcb_temp_c"], 35);
  EXPECT_EQ(f["motor_temp_c"], 45);
  EXPECT_EQ(f["mcu_temp_c"], 40);
  EXPECT_DOUBLE_EQ(f["trip_km"].get<double>(), 12.3);
  EXPECT_EQ(f["trip_time_s"], 1800);
}

TEST(DecodeTool, LockStatusNamesKindAndState) {
  const auto r = decode_text(log_of(0x770, kLockStatus, 1763700000000000));
  ASSERT_EQ(r.lines.size(), 1u);
  const json& f = r.lines[0]["fields"];
  EXPECT_EQ(r.lines[0]["message"], "lock_status");
  EXPECT_EQ(f["lock"], "seat");
  EXPECT_DOUBLE_EQ(f["voltage_v"].get<double>(), 12.0);
  EXPECT_DOUBLE_EQ(f["current_a"].get<double>(), 0.15);
  EXPECT_EQ(f["temp_c"], 25);
  EXPECT_EQ(f["state"], "locked");
  EXPECT_EQ(f["state_raw"], 2);
  EXPECT_EQ(f["bolts"], 1);

  motinova::DecodeOptions custom;
  custom.lock_kinds = {"battery", "frame", "", "", ""};
  custom.lock_state_names[2] = "closed";
  const auto c = decode_text(log_of(0x770, kLockStatus, 1763700000000000), false, custom);
  ASSERT_EQ(c.lines.size(), 1u);
  EXPECT_EQ(c.lines[0]["fields"]["lock"], "battery");
  EXPECT_EQ(c.lines[0]["fields"]["state"], "closed");
}

TEST(DecodeTool, FaultWordListsActiveFaults) {
  // MC fault word: over-current (low 0x0001) and MOS short circuit (high 0x0001).
  motinova::AppFrame f = motinova::make_frame(0x710, motinova::Mode::kReport, 0x11,
                                              std::vector<uint8_t>{0x00, 0x01, 0x00, 0x01});
  const auto encoded = motinova::encode_frame(f);
  std::string hex;
  for (uint8_t b : encoded) hex += fmt::format("{:02X}", b);
  const auto r = decode_text(log_of(0x710, hex, 1763700000000000));
  ASSERT_EQ(r.lines.size(), 1u);
  const json& fields = r.lines[0]["fields"];
  EXPECT_EQ(r.lines[0]["message"], "mc_faults");
  EXPECT_EQ(fields["raw"], 0x00010001);
  ASSERT_EQ(fields["active"].size(), 2u);
  EXPECT_EQ(fields["active"][0]["code"], 10);
  EXPECT_EQ(fields["active"][1]["code"], 25);
  EXPECT_EQ(fields["active"][1]["severity"], "critical");
}

TEST(DecodeTool, CorruptFramesAreCountedNeverPrinted) {
  std::string text = log_of(0x770, kLockStatus, 1763700000000000);
  std::string bad = kLockStatus;
  bad[20] = bad[20] == '0' ? '1' : '0';  // one flipped nibble in DATA: CRC fails
  text += log_of(0x770, bad, 1763700001000000);
  text += "(1763700002.000000) can0 770#55AA0C\n";  // a start that never completes
  text += "this is not a candump line\n";
  const auto r = decode_text(text, /*errors=*/true);
  int messages = 0, errors = 0;
  bool malformed_line_reported = false;
  for (const auto& l : r.lines) {
    if (l.contains("fields")) ++messages;
    if (l.contains("error")) ++errors;
    if (l.value("error", "") == "malformed_line")
      malformed_line_reported = l["line"] == 10;  // 4 + 4 segments, then 2 lines
  }
  EXPECT_EQ(messages, 1);
  EXPECT_EQ(errors, 3);  // bad CRC, truncated start, malformed line
  EXPECT_TRUE(malformed_line_reported);
  EXPECT_EQ(r.summary.reassembly.error(motinova::ReassemblyError::kBadCrc), 1u);
  EXPECT_EQ(r.summary.lines_malformed, 1u);
  EXPECT_NE(r.err.find("bad_crc=1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("line 10"), std::string::npos) << r.err;
}

TEST(DecodeTool, UnknownMessageKeepsRawData) {
  motinova::AppFrame f =
      motinova::make_frame(0x7B0, motinova::Mode::kReport, 0x77, std::vector<uint8_t>{0xDE, 0xAD});
  std::string hex;
  for (uint8_t b : motinova::encode_frame(f)) hex += fmt::format("{:02X}", b);
  const auto r = decode_text(log_of(0x7B0, hex, 1763700000000000));
  ASSERT_EQ(r.lines.size(), 1u);
  EXPECT_EQ(r.lines[0]["message"], "unknown");
  EXPECT_EQ(r.lines[0]["fields"]["data"], "DEAD");
}

TEST(DecodeTool, LittleEndianCrcNeedsTheOption) {
  std::string le = kLockStatus;
  // Reverse the 4 CRC bytes (hex chars before the trailing F0).
  const std::size_t crc = le.size() - 10;
  std::string rev;
  for (int i = 3; i >= 0; --i) rev += le.substr(crc + static_cast<std::size_t>(i) * 2, 2);
  le.replace(crc, 8, rev);
  const auto strict = decode_text(log_of(0x770, le, 1763700000000000));
  EXPECT_TRUE(strict.lines.empty());
  // Nothing decoded is a failure of the run, with the option to try named.
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_NE(strict.err.find("--crc-order auto"), std::string::npos) << strict.err;
  motinova::DecodeOptions automatic;
  automatic.crc_order = motinova::CrcOrder::kAuto;
  const auto r = decode_text(log_of(0x770, le, 1763700000000000), false, automatic);
  EXPECT_EQ(r.exit_code, 0);
  ASSERT_EQ(r.lines.size(), 1u);
  EXPECT_EQ(r.summary.reassembly.crc_little_endian, 1u);
  EXPECT_NE(r.err.find("little-endian"), std::string::npos);
}

TEST(DecodeTool, GarbageOrBinaryInputFailsWithAHint) {
  std::string binary;
  for (int i = 0; i < 4096; ++i) binary += static_cast<char>((i * 131 + 7) & 0xFF);
  const auto bin = decode_text(binary);
  EXPECT_EQ(bin.exit_code, 1);
  EXPECT_TRUE(bin.lines.empty());
  EXPECT_NE(bin.err.find("candump -L"), std::string::npos) << bin.err;
  EXPECT_LT(std::count(bin.err.begin(), bin.err.end(), '\n'), 30);  // not one line per garbage line

  // Well-formed candump lines whose CRCs all fail.
  std::string bad = kLockStatus;
  bad[20] = bad[20] == '0' ? '1' : '0';
  const auto crc = decode_text(log_of(0x770, bad, 1763700000000000));
  EXPECT_EQ(crc.exit_code, 1);
  EXPECT_NE(crc.err.find("--crc-order auto"), std::string::npos) << crc.err;

  EXPECT_EQ(decode_text("").exit_code, 1);
}

// Bus text is untrusted: quotes, backslashes, control characters and bytes beyond ASCII in a
// model-info block still give one valid JSON line with the text preserved.
TEST(DecodeTool, UntrustedTextIsEscaped) {
  std::vector<uint8_t> data(64, ' ');
  const std::string model = "A\"B\\C\nD\x01";
  std::copy(model.begin(), model.end(), data.begin());
  data[10] = 0xC3;  // not valid UTF-8 on its own
  data[11] = 0xFF;
  const auto f = motinova::make_frame(0x710, motinova::Mode::kReport, 0x12, data);
  std::string hex;
  for (uint8_t b : motinova::encode_frame(f)) hex += fmt::format("{:02X}", b);
  const auto r = decode_text(log_of(0x710, hex, 1763700000000000));
  ASSERT_EQ(r.lines.size(), 1u);  // json::parse in decode_text would throw on invalid JSON
  const std::string text = r.lines[0]["fields"]["model"];
  EXPECT_EQ(text.substr(0, 8), model);
  // Bytes beyond ASCII come out as the code points U+00C3 and U+00FF (valid UTF-8).
  EXPECT_EQ(text.substr(8), "  \xC3\x83\xC3\xBF");
}

// The writer prints numbers exactly as nlohmann::json does (the format before issue 12).
TEST(DecodeTool, NumbersPrintAsBefore) {
  for (double v : {25.3, 0.12, 48.0, 1763700000.123956, 1763700000.0, -5.2, 1e-5, 0.0001, 1e16,
                   123456789012345.6, -0.5, 3.0e-7, 21.93}) {
    JsonBuffer mine;
    append_json_double(mine, v);
    EXPECT_EQ(mine.view(), json(v).dump()) << v;
  }
  JsonBuffer s;
  append_json_string(s, "q\"b\\t\tn\nc\x1f");
  EXPECT_EQ(s.view(), json("q\"b\\t\tn\nc\x1f").dump());
}

TEST(DecodeTool, MissingFileIsAnError) {
  DecodeCommandOptions o;
  o.input = "/nonexistent/file.log";
  std::ostringstream out, err;
  EXPECT_EQ(run_decode(o, out, err), 2);
  EXPECT_NE(err.str().find("/nonexistent/file.log"), std::string::npos);
}

}  // namespace
}  // namespace fleetgw::decode
