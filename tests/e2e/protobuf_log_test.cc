// Issue 11: hostile payloads must not flood the log through protobuf. protobuf prints one
// stderr line per invalid UTF-8 string it parses; the fleetgw binary routes those messages
// through its rate-limited log. The real `fleetgw run` with a real mosquitto gets 1,000
// SignedCommand payloads whose key_id is invalid UTF-8; then one genuine command sent with the
// real `fleetgw command` (same topic, QoS 1, so it is handled after all of them) proves they were
// all processed. The log must hold a bounded number of protobuf lines, one of them with the
// count, and none in protobuf's own raw format.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"

namespace {

using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::TempDir;
namespace fs = std::filesystem;

using fleetgw::testing::ChildProcess;
using fleetgw::testing::run_for_exit_code;

using ::fleetgw::testing::read_text_file;
// `fleetgw ARGS...` to the end, its output in `output`; its exit code.
int run_fleetgw(std::vector<std::string> args, const fs::path& output) {
  args.insert(args.begin(), FLEETGW_BINARY);
  return run_for_exit_code(args, output);
}

// A serialized fleetgw.v1.SignedCommand (command = 1, signature = 2: bytes; key_id = 3: string)
// whose key_id is not UTF-8, encoded by hand: protobuf would refuse to serialise it.
std::string hostile_payload(int i) {
  const std::string command = "not a command " + std::to_string(i);
  const std::string signature(64, 's');
  const std::string key_id = std::string("k\xff\xfe", 3) + std::to_string(i % 10);
  std::string p;
  const auto field = [&p](char tag, const std::string& bytes) {
    p += tag;
    p += static_cast<char>(bytes.size());  // all < 128 bytes: a one-byte varint
    p += bytes;
  };
  field('\x0a', command);
  field('\x12', signature);
  field('\x1a', key_id);
  return p;
}

TEST(ProtobufLog, InvalidUtf8FloodGivesBoundedLinesWithACount) {
  TempDir dir("fleetgw-pblog");
  MosquittoBroker broker;
  broker.start();
  const fs::path keygen_out = dir.path() / "keygen.out";
  ASSERT_EQ(run_fleetgw({"keygen", (dir.path() / "operator").string()}, keygen_out), 0);
  std::string trusted;
  {
    std::istringstream lines(read_text_file(keygen_out));
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("operator = \"", 0) == 0) trusted = line;
    }
  }
  ASSERT_FALSE(trusted.empty()) << read_text_file(keygen_out);
  std::ofstream(dir.path() / "quiet.toml") << "[scenario]\nname = \"quiet\"\nduration_s = 3600\n"
                                           << "[[ride]]\nduration_s = 3600\nspeed_kmh = 0\n";
  const fs::path config = dir.path() / "fleetgw.toml";
  std::ofstream(config) << "[vehicle]\nid = \"pblog-bike\"\n[log]\nlevel = \"info\"\n"
                        << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \""
                        << (dir.path() / "quiet.toml").string()
                        << "\"\nspeed = 1\nlockstep = true\n"
                        << "[storage]\npath = \"" << (dir.path() / "fleetgw.db").string()
                        << "\"\n[status]\nsocket = \"" << (dir.path() / "status.sock").string()
                        << "\"\n[mqtt]\nenabled = true\nuri = \"" << broker.uri() << "\"\n"
                        << "[command.trusted_keys]\n"
                        << trusted << "\n";
  const fs::path log = dir.path() / "fleetgw.log";
  ChildProcess gateway({FLEETGW_BINARY, "run", "--config", config.string(), "--duration", "120"},
                       log);

  mqtt::async_client attacker(broker.uri(), "attacker", mqtt::create_options(MQTTVERSION_3_1_1));
  mqtt::connect_options co;
  co.set_clean_session(true);
  attacker.connect(co)->wait();
  // The gateway subscribes once connected: a genuine command answers only then (one published
  // before that is not delivered to it), so send one until it is answered, then the flood, then
  // one again as the "all processed" sentinel.
  const auto send_genuine = [&](const std::string& name, int timeout_s) {
    const fs::path out = dir.path() / (name + ".out");
    const int rc =
        run_fleetgw({"command", "--vehicle", "pblog-bike", "--lock", "seat", "--action", "unlock",
                     "--key", (dir.path() / "operator.pem").string(), "--key-id", "operator",
                     "--broker", broker.uri(), "--timeout-s", std::to_string(timeout_s)},
                    out);
    return std::make_pair(rc, read_text_file(out));
  };
  auto first = send_genuine("first", 2);
  for (int attempt = 1; attempt < 10 && first.first != 0 && first.first != 1; ++attempt) {
    first = send_genuine("first", 2);
  }
  ASSERT_TRUE(first.first == 0 || first.first == 1) << first.second << read_text_file(log);

  constexpr int kPayloads = 1000;
  for (int i = 0; i < kPayloads; ++i) {
    attacker.publish("fleet/v1/pblog-bike/cmd", hostile_payload(i), 1, false)->wait();
  }
  const auto sentinel = send_genuine("sentinel", 20);
  ASSERT_TRUE(sentinel.first == 0 || sentinel.first == 1) << sentinel.second << read_text_file(log);
  attacker.disconnect()->wait();
  EXPECT_EQ(gateway.stop(), 0) << read_text_file(log);

  const std::string text = read_text_file(log);
  std::size_t protobuf_lines = 0, raw_lines = 0;
  std::uint64_t counted = 0;
  std::istringstream in(text);
  const std::regex repeated(R"(repeated (\d+) (more )?times)");
  for (std::string line; std::getline(in, line);) {
    if (line.find("[libprotobuf") != std::string::npos) ++raw_lines;
    if (line.find("protobuf: ") == std::string::npos) continue;
    ++protobuf_lines;
    std::cerr << "  log: " << line.substr(0, 400) << "\n";
    std::smatch m;
    if (std::regex_search(line, m, repeated)) counted += std::stoull(m[1].str());
  }
  EXPECT_EQ(raw_lines, 0u) << "no line in protobuf's own format\n" << text.substr(0, 4000);
  EXPECT_GE(protobuf_lines, 1u) << "the invalid strings are reported\n" << text.substr(0, 4000);
  EXPECT_LE(protobuf_lines, 6u) << "bounded, not one line per payload";
  // The first occurrence is logged; every other one is in a count.
  EXPECT_GE(counted + 1, static_cast<std::uint64_t>(kPayloads)) << text.substr(0, 4000);
}

}  // namespace
