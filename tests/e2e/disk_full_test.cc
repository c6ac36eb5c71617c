// Issue 11, item 1-2: a full disk under the real `fleetgw run`. The store lives on a small
// tmpfs; a simulated ride with recurring faults runs at high speed; a filler file takes every
// free byte of the tmpfs (and keeps taking what is freed) until the store cannot write, then is
// deleted. The process must never exit, storage must be reported failing and then OK again by
// itself, inspection (`fleetgw db`) must work meanwhile, and no fault event may be lost
// compared with the same ride on a roomy disk. Runs with the uplink off and on (real mosquitto);
// with the uplink on, an operator sends a signed command with the real `fleetgw command` while
// the disk is full: it gets exactly one definite result on the broker (published directly,
// stored=false, bound to the command's SHA-256), and no fault or ride record is lost.
// Needs root for mount(2) (CI runs as root); skipped otherwise.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <vector>

#include <mqtt/async_client.h>

#include <mutex>
#include <optional>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::TempDir;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

constexpr double kSpeed = 40;        // sim.speed
constexpr double kBusSeconds = 720;  // the reference run ends after this much bus time (18 s)
constexpr int kFaultPeriodS = 40;    // an MC over-heat is raised and cleared every 40 s of bus time

using ::fleetgw::testing::read_text_file;
// "2026-11-27 17:55:34.898 warning ...": the time of day in seconds (the log's own format).
double time_of_day_s(const std::string& line) {
  int h = 0, m = 0;
  double s = 0;
  if (line.size() < 23 || std::sscanf(line.c_str() + 11, "%d:%d:%lf", &h, &m, &s) != 3) return -1;
  return h * 3600.0 + m * 60.0 + s;
}

using ::fleetgw::testing::wait_until;
// A steady ride with an MC over-heat raised and cleared every kFaultPeriodS seconds.
std::string write_scenario(const fs::path& dir) {
  std::ostringstream s;
  s << "[scenario]\nname = \"disk-full\"\nduration_s = 3600\n"
    << "start_utc = 2024-07-01T08:00:00Z\n[bike]\nseed = 77\nsoc_pct = 90\n"
    << "[[ride]]\nduration_s = 3600\nspeed_kmh = 21\n";
  for (int t = 10; t < 3600; t += kFaultPeriodS) {
    s << "[[event]]\nat_s = " << t << "\naction = \"fault\"\nnode = \"mc\"\n"
      << "fault = \"over_heat_protect\"\n[[event]]\nat_s = " << t + kFaultPeriodS / 2
      << "\naction = \"clear\"\nnode = \"mc\"\nfault = \"over_heat_protect\"\n";
  }
  const auto path = dir / "disk-full.toml";
  std::ofstream(path) << s.str();
  return path.string();
}

std::string write_config(const fs::path& dir, const fs::path& db, const std::string& scenario,
                         const std::string& broker_uri, const std::string& trusted_key_line = "") {
  std::ostringstream c;
  c << "[vehicle]\nid = \"disk-full-bike\"\n[log]\nlevel = \"info\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << scenario << "\"\nspeed = " << kSpeed
    << "\nlockstep = true\n[storage]\npath = \"" << db.string() << "\"\nmax_mb = 4\n"
    << "[status]\nsocket = \"" << (dir / "status.sock").string() << "\"\n";
  if (!broker_uri.empty()) {
    c << "[mqtt]\nenabled = true\nuri = \"" << broker_uri << "\"\ntelemetry_qos = 1\n"
      << "reconnect_min_ms = 100\nreconnect_max_ms = 500\n";
  }
  if (!trusted_key_line.empty()) c << "[command.trusted_keys]\n" << trusted_key_line << "\n";
  const auto path = dir / "fleetgw.toml";
  std::ofstream(path) << c.str();
  return path.string();
}

// `fleetgw ARGS...` as a child process, stdout and stderr in `output` (started afresh).
ChildProcess spawn(const std::vector<std::string>& args, const fs::path& output) {
  fs::remove(output);
  std::vector<std::string> argv{FLEETGW_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  return ChildProcess(std::move(argv), output);
}

// Runs `fleetgw ...` to completion; returns exit code, stdout+stderr in `out`.
int run_fleetgw(const std::vector<std::string>& args, const fs::path& scratch, std::string& out) {
  const fs::path file = scratch / "cmd.out";
  const int rc = spawn(args, file).wait();
  out = read_text_file(file);
  return rc;
}

struct StoreCounts {
  std::int64_t faults = -1, telemetry = -1, rides = -1;
  std::int64_t bus_us = -1;  // how far the store's newest telemetry is past the ride's start
  std::string integrity;
};

StoreCounts read_store(const fs::path& db, std::int64_t window_us) {
  StoreCounts c;
  fleetgw::testing::SqliteReader reader(db);
  if (!reader.ok()) return c;
  auto scalar = [&](const std::string& sql) { return reader.scalar(sql); };
  c.faults = scalar(
      "SELECT count(*) FROM fault_events WHERE first_seen_us - (SELECT min(start_us) FROM rides) "
      "<= " +
      std::to_string(window_us));
  c.telemetry = scalar("SELECT count(*) FROM telemetry");
  c.bus_us =
      scalar("SELECT (SELECT max(ts_us) FROM telemetry) - (SELECT min(start_us) FROM rides)");
  c.rides = scalar("SELECT count(*) FROM rides");
  c.integrity = reader.text("PRAGMA integrity_check");
  return c;
}

// Keeps the file system holding `path` full: appends to `path` whenever a byte is free.
class DiskFiller {
 public:
  explicit DiskFiller(fs::path path) : path_(std::move(path)) {
    thread_ = std::thread([this] { run(); });
  }
  ~DiskFiller() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  void remove() {
    stop();
    fs::remove(path_);
  }

 private:
  void run() {
    std::FILE* f = std::fopen(path_.c_str(), "ab");
    if (f == nullptr) return;
    std::setvbuf(f, nullptr, _IONBF, 0);
    const std::vector<char> block(64 * 1024, 'x');
    while (!stop_) {
      for (std::size_t size = block.size(); size >= 512 && !stop_;) {
        if (std::fwrite(block.data(), 1, size, f) != size) {
          std::clearerr(f);
          size /= 2;
        }
      }
      std::this_thread::sleep_for(10ms);
    }
    std::fclose(f);
  }

  fs::path path_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

class Tmpfs {
 public:
  Tmpfs(const fs::path& where, const std::string& size) : where_(where) {
    fs::create_directories(where);
    mounted_ = ::mount("tmpfs", where.c_str(), "tmpfs", 0, ("size=" + size).c_str()) == 0;
  }
  ~Tmpfs() {
    if (mounted_) ::umount2(where_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }

 private:
  fs::path where_;
  bool mounted_ = false;
};

// The status document, or null when the socket does not answer.
nlohmann::json status_json(const fs::path& dir) {
  std::string out;
  run_fleetgw({"status", "--json", "--socket", (dir / "status.sock").string()}, dir, out);
  // The document, then (exit 1) an "ATTENTION: ..." line on stderr, both in `out`.
  const auto brace = out.find('{');
  const auto last = out.rfind('}');
  if (brace == std::string::npos || last == std::string::npos || last < brace) return nullptr;
  return nlohmann::json::parse(out.substr(brace, last - brace + 1), nullptr, false);
}

// storage.failing from `fleetgw status --json`; nullopt when the socket does not answer.
std::optional<bool> storage_failing(const fs::path& dir) {
  const auto j = status_json(dir);
  if (!j.is_object() || !j.contains("storage") || !j["storage"].contains("failing")) {
    return std::nullopt;
  }
  return j["storage"]["failing"].get<bool>();
}

// storage.failed_writes from `fleetgw status --json`; -1 when the socket does not answer.
std::int64_t failed_writes(const fs::path& dir) {
  const auto j = status_json(dir);
  if (!j.is_object() || !j.contains("storage")) return -1;
  return j["storage"].value("failed_writes", std::int64_t{-1});
}

// Every CommandResult published on the vehicle's result topic, as the backend sees them.
class ResultWatcher {
 public:
  ResultWatcher(const std::string& uri, const std::string& vehicle)
      : client_(uri, "disk-full-backend", mqtt::create_options(MQTTVERSION_3_1_1)) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope env;
      if (!env.ParseFromString(m->to_string()) || !env.has_command_result()) return;
      std::lock_guard lock(mu_);
      results_.push_back(env.command_result());
    });
    mqtt::connect_options co;
    co.set_clean_session(true);
    client_.connect(co)->wait();
    client_.subscribe("fleet/v1/" + vehicle + "/cmd/result", 1)->wait();
  }
  ~ResultWatcher() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(1));
    } catch (...) {
    }
  }
  std::vector<fleetgw::v1::CommandResult> for_id(const std::string& id) {
    std::lock_guard lock(mu_);
    std::vector<fleetgw::v1::CommandResult> out;
    for (const auto& r : results_) {
      if (r.command_id() == id) out.push_back(r);
    }
    return out;
  }

 private:
  mqtt::async_client client_;
  std::mutex mu_;
  std::vector<fleetgw::v1::CommandResult> results_;
};

std::string to_hex(const std::string& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (const unsigned char b : bytes) {
    out += kDigits[b >> 4];
    out += kDigits[b & 15];
  }
  return out;
}

// `fleetgw keygen`: the operator key (outside the full disk) and its trusted-keys line.
std::string make_operator_key(const fs::path& dir) {
  std::string out;
  EXPECT_EQ(run_fleetgw({"keygen", (dir / "operator").string()}, dir, out), 0) << out;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("operator = \"", 0) == 0) return line;
  }
  ADD_FAILURE() << "keygen printed no trusted-keys line\n" << out;
  return {};
}

// Fault events raised in the first (kBusSeconds - 2 periods) of the ride, counted from the ride's
// start (bus time starts at the wall clock of the run): the last period may be cut by the end.
// Faults counted: those first seen within this long after the ride opened. Faults are raised
// every kFaultPeriodS from 10 s into the scenario and the ride opens within the first seconds,
// so the window ends about half a period away from any fault: how soon a loaded machine
// notices the ride's start or a fault cannot move one across the edge.
std::int64_t fault_window_us() {
  return static_cast<std::int64_t>(kBusSeconds - 2 * kFaultPeriodS - kFaultPeriodS / 4) * 1'000'000;
}

StoreCounts reference_run(const fs::path& base, const std::string& scenario) {
  const fs::path dir = base / "reference";
  fs::create_directories(dir);
  const auto config = write_config(dir, dir / "fleetgw.db", scenario, "");
  std::string out;
  const int rc = run_fleetgw({"run", "--config", config, "--bus-duration",
                              std::to_string(kBusSeconds), "--duration", "120"},
                             dir, out);
  EXPECT_EQ(rc, 0) << out;
  return read_store(dir / "fleetgw.db", fault_window_us());
}

void disk_full_round(bool uplink) {
  TempDir base("fleetgw-diskfull");
  const fs::path disk = base.path() / "disk";
  Tmpfs tmpfs(disk, "8m");
  if (!tmpfs.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  std::optional<MosquittoBroker> broker;
  std::optional<ResultWatcher> backend;
  if (uplink) {
    broker.emplace();
    broker->start();
    backend.emplace(broker->uri(), "disk-full-bike");
  }
  const std::string scenario = write_scenario(base.path());
  const StoreCounts reference = reference_run(base.path(), scenario);
  ASSERT_GT(reference.faults, 10) << "the scenario raises and clears faults";
  ASSERT_GT(reference.rides, 0);
  const std::string trusted_key = uplink ? make_operator_key(base.path()) : std::string();

  const fs::path db = disk / "fleetgw.db";
  const auto config =
      write_config(base.path(), db, scenario, uplink ? broker->uri() : std::string(), trusted_key);
  const fs::path log = base.path() / "fleetgw.log";
  // The service runs until the test stops it (the scenario's hour is far longer than the test):
  // a loaded machine that slows the filling and recovery steps cannot make the run end first.
  ChildProcess service = spawn({"run", "--config", config, "--duration", "150"}, log);
  ASSERT_TRUE(wait_until([&] { return fs::exists(base.path() / "status.sock"); }, 10s))
      << read_text_file(log);

  // Inspection while the service runs: read-only, works, changes nothing.
  std::string stats;
  ASSERT_TRUE(wait_until(
      [&] {
        if (run_fleetgw({"db", "stats", "--db", db.string()}, base.path(), stats) != 0) {
          return false;
        }
        const auto j = nlohmann::json::parse(stats.substr(stats.find('{')), nullptr, false);
        return j.is_object() && j["tables"]["telemetry"].get<int>() > 20;
      },
      10s))
      << stats;
  EXPECT_FALSE(fs::exists(db.string() + ".corrupt")) << "inspection moved nothing";
  EXPECT_EQ(storage_failing(base.path()), false) << "storage OK before the disk fills";

  // Fill the disk and keep it full.
  DiskFiller filler(disk / "filler");
  const auto full_since = std::chrono::steady_clock::now();
  const bool failure_logged = wait_until(
      [&] { return read_text_file(log).find("storage: write failed") != std::string::npos; }, 30s);
  ASSERT_TRUE(failure_logged) << "the store never failed with the disk full\n"
                              << read_text_file(log);
  const auto first_failure = std::chrono::steady_clock::now();
  ASSERT_TRUE(wait_until([&] { return storage_failing(base.path()) == true; }, 5s))
      << "status must say storage is failing within 5 s of the first failure\n"
      << status_json(base.path()).dump() << "\n"
      << read_text_file(log);
  const auto attention = std::chrono::steady_clock::now();
  {
    std::string out;
    EXPECT_EQ(run_fleetgw({"status", "--socket", (base.path() / "status.sock").string()},
                          base.path(), out),
              1)
        << "needs attention\n"
        << out;
    EXPECT_NE(out.find("storage"), std::string::npos) << out;
  }

  // Stay full while the store keeps retrying (status counts the failed writes).
  const std::int64_t failed_at_attention = failed_writes(base.path());
  ASSERT_GT(failed_at_attention, 0);
  EXPECT_TRUE(
      wait_until([&] { return failed_writes(base.path()) >= failed_at_attention + 3; }, 10s))
      << "the store retries while the disk is full";

  std::string command_id;
  if (uplink) {
    // An operator sends a signed command while the disk is full: exactly one definite result on
    // the broker, published directly (not stored), bound to the signed bytes.
    const fs::path tool_out = base.path() / "command.out";
    ChildProcess tool =
        spawn({"command", "--vehicle", "disk-full-bike", "--lock", "seat", "--action", "unlock",
               "--key", (base.path() / "operator.pem").string(), "--key-id", "operator", "--broker",
               broker->uri(), "--timeout-s", "10"},
              tool_out);
    const int tool_rc = tool.wait();
    const std::string text = read_text_file(tool_out);
    ASSERT_TRUE(tool_rc == 0 || tool_rc == 1) << "a definite result, not silence\n" << text;
    const auto brace = text.find('{');
    ASSERT_NE(brace, std::string::npos) << text;
    const auto answer =
        nlohmann::json::parse(text.substr(brace, text.find('\n', brace) - brace), nullptr, false);
    ASSERT_TRUE(answer.is_object()) << text;
    const std::string id = answer.value("command_id", "");
    ASSERT_FALSE(id.empty()) << text;
    EXPECT_EQ(answer.value("stored", true), false) << "published directly\n" << text;
    EXPECT_EQ(answer.value("command_sha256", "").size(), 64u) << text;
    // What the broker carried for that id: one result, the same one. Wait a little past the
    // first so that a second (duplicate) result would be seen.
    ASSERT_TRUE(wait_until([&] { return !backend->for_id(id).empty(); }, 5s));
    const auto seen_one = std::chrono::steady_clock::now();
    wait_until([&] { return backend->for_id(id).size() > 1; }, 2s);
    const auto on_broker = backend->for_id(id);
    ASSERT_EQ(on_broker.size(), 1u) << "exactly one result for " << id;
    EXPECT_FALSE(on_broker[0].stored());
    EXPECT_EQ(to_hex(on_broker[0].command_sha256()), answer.value("command_sha256", ""));
    EXPECT_NE(on_broker[0].result(), fleetgw::v1::COMMAND_RESULT_CODE_UNSPECIFIED);
    std::cerr << "command while full: " << answer.dump() << " (on the broker "
              << std::chrono::duration_cast<std::chrono::milliseconds>(
                     std::chrono::steady_clock::now() - seen_one)
                     .count()
              << " ms after the first)\n";
    command_id = id;
  }
  ASSERT_TRUE(service.running()) << "the service exited on a full disk\n" << read_text_file(log);

  // Space returns.
  filler.remove();
  const auto freed = std::chrono::steady_clock::now();
  EXPECT_TRUE(wait_until([&] { return storage_failing(base.path()) == false; }, 5s))
      << "status must be back to OK within 5 s of space returning";
  const auto status_ok = std::chrono::steady_clock::now();
  EXPECT_TRUE(wait_until(
      [&] {
        return read_text_file(log).find("pending records written, storage OK") != std::string::npos;
      },
      5s))
      << "recovery is automatic and logged\n"
      << read_text_file(log);
  const auto recovered = std::chrono::steady_clock::now();
  ASSERT_TRUE(service.running());
  if (!command_id.empty()) {
    // Once the store accepts writes the result is journaled, not published a second time.
    wait_until([&] { return backend->for_id(command_id).size() > 1; }, 2s);
    EXPECT_EQ(backend->for_id(command_id).size(), 1u) << "recovery answers no command twice";
  }
  // Every fault of the compared window must have been raised before the run is stopped.
  EXPECT_TRUE(wait_until(
      [&] { return read_store(db, fault_window_us()).bus_us >= kBusSeconds * 1'000'000; }, 60s))
      << "the ride went past " << kBusSeconds << " s of bus time";
  EXPECT_EQ(service.stop(), 0) << read_text_file(log);
  const std::string text = read_text_file(log);
  // The same error is not logged on every retry: each distinct failure message at most once per
  // 10 s, plus one line per message that reports its repetitions when writing works again.
  const auto failing_s =
      std::chrono::duration_cast<std::chrono::seconds>(recovered - first_failure).count();
  std::map<std::string, std::size_t> per_message;  // message (after the timestamp) -> lines
  std::size_t recaps = 0;
  std::vector<double> eviction_at_s;  // time of day of each eviction line, in seconds
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.find("storage") == std::string::npos) continue;
    std::cerr << "  log: " << line.substr(0, 300) << "\n";
    if (line.find("to make room") != std::string::npos ||
        line.find("passes over the last") != std::string::npos) {
      eviction_at_s.push_back(time_of_day_s(line));
    }
    const auto at = line.find("storage: write failed");
    if (at == std::string::npos) continue;
    if (line.find("repeated") != std::string::npos) {
      ++recaps;
    } else {
      ++per_message[line.substr(at)];
    }
  }
  EXPECT_LE(per_message.size(), 4u) << "a handful of distinct failure messages\n" << text;
  for (const auto& [message, n] : per_message) {
    EXPECT_LE(n, static_cast<std::size_t>(1 + failing_s / 10))
        << "repeated identical errors are rate-limited: " << message;
  }
  EXPECT_LE(recaps, per_message.size()) << text;
  // Evictions forced by the full disk happen at every retry; the log sums them per 10 s. They
  // start when the disk fills, which on a loaded machine can be well before the first failed
  // write, so the rate is judged line to line rather than against the failure window.
  EXPECT_FALSE(eviction_at_s.empty()) << "the full disk forced no eviction\n" << text;
  for (std::size_t i = 1; i < eviction_at_s.size(); ++i) {
    EXPECT_GE(eviction_at_s[i] - eviction_at_s[i - 1], 9.9)
        << "eviction lines " << i << " and " << i + 1 << " closer than 10 s\n"
        << text;
  }

  const StoreCounts after = read_store(db, fault_window_us());
  EXPECT_EQ(after.integrity, "ok");
  EXPECT_EQ(after.faults, reference.faults) << "no fault event lost to the full disk";
  EXPECT_EQ(after.rides, reference.rides) << "no ride lost to the full disk";
  const auto ms = [](auto d) {
    return std::chrono::duration_cast<std::chrono::milliseconds>(d).count();
  };
  std::cerr << "figures: first failure after " << ms(first_failure - full_since)
            << " ms of full disk; status attention " << ms(attention - first_failure)
            << " ms after it; status OK " << ms(status_ok - freed)
            << " ms after space returned; recovered " << ms(recovered - freed) << " ms; "
            << per_message.size() << " distinct 'write failed' messages; faults " << after.faults
            << "/" << reference.faults << ", rides " << after.rides << "/" << reference.rides
            << "\n";
}

TEST(DiskFull, UplinkOffServiceSurvivesReportsAndRecovers) {
  disk_full_round(false);
}

TEST(DiskFull, UplinkOnServiceSurvivesReportsAndRecovers) {
  disk_full_round(true);
}

TEST(DbTool, RefusesATextFileAndLeavesItAlone) {
  TempDir dir("fleetgw-dbtool");
  const fs::path text = dir.path() / "ride.log";
  std::ofstream(text) << "(1700000000.000000) can0 710#55AA0C1010\n";
  const std::string before = read_text_file(text);
  std::string out;
  const int rc = run_fleetgw({"db", "stats", "--db", text.string()}, dir.path(), out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("not a fleetgw store"), std::string::npos) << out;
  EXPECT_EQ(read_text_file(text), before);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir.path())) {
    names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"cmd.out", "ride.log"})) << "nothing created or moved";
  const fs::path missing = dir.path() / "nope.db";
  EXPECT_EQ(run_fleetgw({"db", "stats", "--db", missing.string()}, dir.path(), out), 2);
  EXPECT_NE(out.find("no database"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(missing));
}

TEST(Service, RefusesAStorageDirectoryThatDoesNotExist) {
  TempDir dir("fleetgw-nodir");
  const fs::path db = dir.path() / "missing" / "fleetgw.db";
  std::ofstream(dir.path() / "s.toml") << "[scenario]\nname = \"x\"\nduration_s = 10\n"
                                       << "[[ride]]\nduration_s = 10\nspeed_kmh = 0\n";
  const auto config = write_config(dir.path(), db, (dir.path() / "s.toml").string(), "");
  std::string out;
  EXPECT_NE(run_fleetgw({"run", "--config", config, "--duration", "5"}, dir.path(), out), 0);
  EXPECT_NE(out.find("storage.path"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir.path() / "missing")) << "never created";
}

}  // namespace
