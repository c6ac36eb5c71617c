// The real `fleetgw decode --format table|json|csv`: the summary on stderr is the one line for
// people by default, one JSON object or key,value CSV for scripts (with nothing else on stderr),
// and the decoded JSON lines on stdout are byte for byte the same in every format.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "gateway/can/candump.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"
#include "tests/config/cli_test_util.h"

namespace fleetgw::decode {
namespace {

using nlohmann::json;
using testing::run;

constexpr const char* kBin = FLEETGW_BIN;
// Spec §2.5 lock status vector.
constexpr std::string_view kLockStatus = "55AA0C1210102EE000964102000100000000000000003C3501BDF0";

std::string candump_of(uint16_t id, std::string_view frame_hex, int64_t start_us,
                       std::size_t* frames = nullptr) {
  std::vector<uint8_t> bytes;
  for (std::size_t i = 0; i + 1 < frame_hex.size(); i += 2) {
    bytes.push_back(
        static_cast<uint8_t>(std::stoi(std::string(frame_hex.substr(i, 2)), nullptr, 16)));
  }
  std::string log;
  int64_t t = start_us;
  const auto segments = motinova::segment(id, bytes);
  for (const auto& can : segments) {
    log += can::candump::format_line(motinova::Micros(t), "can0", can) + "\n";
    t += 100;
  }
  if (frames) *frames += segments.size();
  return log;
}

std::string flipped_crc_frame() {
  std::string bad(kLockStatus);
  bad[20] = bad[20] == '0' ? '1' : '0';  // one nibble of DATA: the CRC fails
  return bad;
}

class DecodeCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::path(::testing::TempDir()) /
           ("decode_cli_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // One good message, one failing its CRC, one malformed line.
  std::string mixed_log() {
    std::string text = candump_of(0x770, kLockStatus, 1763700000000000, &can_frames_);
    text += candump_of(0x770, flipped_crc_frame(), 1763700001000000, &can_frames_);
    text += "this is not a candump line\n";
    const auto path = dir_ / "mixed.log";
    testing::write_text_file(path, text);
    return path.string();
  }
  testing::Result decode(const std::vector<std::string>& args) {
    std::vector<std::string> argv{kBin, "decode"};
    argv.insert(argv.end(), args.begin(), args.end());
    return run(argv, dir_);
  }

  std::filesystem::path dir_;
  std::size_t can_frames_ = 0;
};

TEST_F(DecodeCli, TableIsTheDefaultOneLineSummary) {
  const auto log = mixed_log();
  const auto plain = decode({log});
  const auto table = decode({log, "--format", "table"});
  EXPECT_EQ(plain.code, 0) << plain.err;
  EXPECT_EQ(table.code, 0) << table.err;
  EXPECT_EQ(plain.err, table.err);
  EXPECT_EQ(plain.out, table.out);
  // The malformed line reported, then the summary line.
  EXPECT_NE(plain.err.find("line 9"), std::string::npos) << plain.err;
  EXPECT_NE(plain.err.find("decode: " + std::to_string(can_frames_) + " CAN frames, 1 messages"),
            std::string::npos)
      << plain.err;
  EXPECT_NE(plain.err.find("bad_crc=1"), std::string::npos) << plain.err;
}

TEST_F(DecodeCli, JsonSummaryIsOneObjectAndNothingElse) {
  const auto log = mixed_log();
  const auto plain = decode({log});
  const auto r = decode({log, "--format", "json"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, plain.out);  // the decoded JSON lines do not change
  ASSERT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  const json doc = json::parse(r.err);  // throws (fails the test) if stderr is not one document
  EXPECT_EQ(doc["can_frames"], can_frames_);
  EXPECT_EQ(doc["messages"], 1);
  EXPECT_EQ(doc["unknown_messages"], 0);
  EXPECT_EQ(doc["malformed_lines"], 1);
  EXPECT_EQ(doc["non_data_frames"], 0);
  EXPECT_EQ(doc["frame_errors"]["bad_crc"], 1);
  // Every error kind is present, zeros included: stable keys for scripts.
  EXPECT_EQ(doc["frame_errors"].size(), motinova::kReassemblyErrorKinds);
  EXPECT_EQ(doc["frame_errors"]["truncated"], 0);
  EXPECT_EQ(doc["crc_order_seen"]["be"], 1);
  EXPECT_EQ(doc["crc_order_seen"]["le"], 0);
  EXPECT_EQ(doc["input"], log);
  EXPECT_TRUE(doc["hint"].is_null());
}

TEST_F(DecodeCli, CsvSummaryIsKeyValueRows) {
  const auto log = mixed_log();
  const auto plain = decode({log});
  const auto r = decode({log, "--format", "csv"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, plain.out);
  EXPECT_EQ(r.err.rfind("key,value\r\n", 0), 0u) << r.err;
  for (const std::string& row :
       {"can_frames," + std::to_string(can_frames_), std::string("messages,1"),
        std::string("frame_errors.bad_crc,1"), std::string("frame_errors.truncated,0"),
        std::string("malformed_lines,1"), std::string("crc_order_seen.be,1"), std::string("hint,"),
        "input," + log}) {
    EXPECT_NE(r.err.find("\r\n" + row + "\r\n"), std::string::npos) << row << "\n" << r.err;
  }
  EXPECT_EQ(r.err.find("not a candump"), std::string::npos) << r.err;  // no line reports
  // Every record is a key,value pair: 1 header + one row per key.
  const auto rows = std::count(r.err.begin(), r.err.end(), '\n');
  EXPECT_EQ(rows, 1 + 9 + static_cast<long>(motinova::kReassemblyErrorKinds)) << r.err;
}

TEST_F(DecodeCli, NothingDecodedPutsTheHintInTheDocument) {
  std::size_t ignored = 0;
  const auto path = dir_ / "bad.log";
  testing::write_text_file(path, candump_of(0x770, flipped_crc_frame(), 1763700000000000, &ignored));
  const auto r = decode({path.string(), "--format", "json"});
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  const json doc = json::parse(r.err);
  EXPECT_EQ(doc["messages"], 0);
  ASSERT_TRUE(doc["hint"].is_string()) << r.err;
  EXPECT_NE(doc["hint"].get<std::string>().find("--crc-order auto"), std::string::npos) << r.err;

  const auto table = decode({path.string()});
  EXPECT_EQ(table.code, 1);
  EXPECT_NE(table.err.find("decode: no valid MOTINOVA message"), std::string::npos) << table.err;
  EXPECT_NE(table.err.find("--crc-order auto"), std::string::npos) << table.err;
}

TEST_F(DecodeCli, UnknownFormatIsAUsageError) {
  const auto r = decode({mixed_log(), "--format", "xml"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(r.out.empty());
}

}  // namespace
}  // namespace fleetgw::decode
