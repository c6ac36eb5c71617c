// Network strings are data, not text: key ids, vehicle ids and lock kinds that are cut inside a
// code point or carry control characters never break a stored result, its serialization, the
// log, or `fleetgw db export` (the real binary on the real store file).
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gateway/common/untrusted_text.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

const std::string kCutInsideE = std::string(63, 'a') + "\xC3\xA9";  // a cut at 64 splits the é

// A SignedCommand with a chosen key id and vehicle/lock, signed with the rig's trusted key.
std::string crafted(Rig& rig, std::string_view lock, std::string key_id, std::string vehicle,
                    std::string id) {
  const Micros now = rig.bus.now();
  auto cmd = make_command(vehicle, lock, "lock", now, now + 60s, std::move(id));
  return sign_command(*cmd, rig.key, key_id);
}

// Routes spdlog's default logger into a string for the test's lifetime (message text only).
class LogCapture {
 public:
  LogCapture() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(text_);
    sink->set_pattern("%v");
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink));
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  std::vector<std::string> lines() const {
    std::vector<std::string> out;
    std::istringstream in(text_.str());
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
  }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::logger> previous_;
};

// Every command-result payload in the outbox parses and carries valid UTF-8.
std::vector<v1::CommandResult> outbox_results(storage::Store& store) {
  std::vector<v1::CommandResult> out;
  for (const auto& e : store.peek_outbox(1000, 1 << 20)) {
    v1::CommandResult r;
    EXPECT_TRUE(r.ParseFromArray(e.payload.data(), static_cast<int>(e.payload.size())));
    out.push_back(r);
  }
  return out;
}

struct BinaryRun {
  int exit_code = -1;
  std::string out;
};

// Runs the fleetgw binary; stdout is captured, stderr goes to `err_file`.
BinaryRun run_binary(const std::string& args, const std::filesystem::path& err_file) {
  BinaryRun r;
  const std::string cmd = std::string(FLEETGW_BIN) + " " + args + " 2>" + err_file.string();
  FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf{};
  while (const std::size_t n = fread(buf.data(), 1, buf.size(), p)) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(HostileStrings, KeyIdCutInsideACodePointStillGivesAValidPublishedResult) {
  Rig rig;
  rig.bus.run_for(2s);
  const auto* r = rig.run(crafted(rig, "seat", kCutInsideE, kVehicle, "cmd-key-utf8"), 2s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "unknown_key") << r->reason();
  EXPECT_TRUE(common::is_valid_utf8(r->reason()));
  EXPECT_NE(r->reason().find(std::string(60, 'a')), std::string::npos) << r->reason();
  std::string bytes;
  EXPECT_TRUE(r->SerializeToString(&bytes));
  const auto queued = outbox_results(*rig.store);
  ASSERT_EQ(queued.size(), 1u);
  EXPECT_EQ(queued[0].command_id(), "cmd-key-utf8");
  EXPECT_EQ(queued[0].reason(), r->reason());
}

TEST(HostileStrings, LockKindAndVehicleIdCutInsideACodePointKeepDbExportWorking) {
  Rig rig;
  rig.bus.run_for(2s);
  // Authenticated (trusted key), so journaled with a row in command_results.
  const auto* lock = rig.run(crafted(rig, kCutInsideE, kKeyId, kVehicle, "cmd-lock-utf8"), 2s);
  ASSERT_NE(lock, nullptr);
  EXPECT_EQ(reason_code(*lock), "lock_not_fitted") << lock->reason();
  EXPECT_TRUE(common::is_valid_utf8(lock->reason()));
  const auto* vehicle = rig.run(crafted(rig, "seat", kKeyId, kCutInsideE, "cmd-veh-utf8"), 2s);
  ASSERT_NE(vehicle, nullptr);
  EXPECT_EQ(reason_code(*vehicle), "wrong_vehicle") << vehicle->reason();
  EXPECT_TRUE(common::is_valid_utf8(vehicle->reason()));
  EXPECT_EQ(outbox_results(*rig.store).size(), 2u);
  // A genuine command afterwards is answered and exported as well.
  const auto* ok = rig.run(rig.payload("seat", "unlock", "cmd-after"));
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << ok->reason();

  rig.forwarder.service = nullptr;
  rig.service.reset();
  rig.store.reset();  // the technician's tool opens the file on its own
  const auto err_file = rig.dir.path() / "export.err";
  const BinaryRun exported =
      run_binary("db export --db " + rig.db_path.string() + " --table command_results", err_file);
  std::ifstream err_in(err_file);
  const std::string err((std::istreambuf_iterator<char>(err_in)), {});
  ASSERT_EQ(exported.exit_code, 0) << exported.out << err;
  std::istringstream lines(exported.out);
  std::set<std::string> ids;
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    nlohmann::json row;
    ASSERT_NO_THROW(row = nlohmann::json::parse(line)) << line;
    ASSERT_NO_THROW((void)row.dump()) << line;  // dump() throws on invalid UTF-8
    ids.insert(row.value("command_id", ""));
  }
  EXPECT_TRUE(ids.contains("cmd-lock-utf8"));
  EXPECT_TRUE(ids.contains("cmd-after"));
}

TEST(HostileStrings, NewlineInAnUnauthenticatedKeyIdCannotWriteALogLine) {
  LogCapture log;
  Rig rig;
  rig.bus.run_for(2s);
  const std::string forged_line = "[2026-11-23 08:00:00.000] [info] command cmd-x: succeeded";
  const std::string key_id = "evil\n" + forged_line + "\r\x1b[2K";
  const auto* r = rig.run(crafted(rig, "seat", key_id, kVehicle, "cmd-log-inject"), 2s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "unknown_key");
  EXPECT_EQ(r->reason().find('\n'), std::string::npos);
  EXPECT_EQ(r->reason().find('\x1b'), std::string::npos);
  bool saw_escaped = false;
  for (const auto& line : log.lines()) {
    // Every line is one of the gateway's own messages, none starts with the forged text.
    EXPECT_NE(line.rfind("[2026", 0), 0u) << line;
    EXPECT_EQ(line.find('\r'), std::string::npos) << line;
    if (line.find("evil\\n[2026") != std::string::npos) saw_escaped = true;
  }
  EXPECT_TRUE(saw_escaped) << "the rejection should be logged with the key id escaped";
}

}  // namespace
}  // namespace fleetgw::command::testing
