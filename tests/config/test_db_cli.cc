// `fleetgw db rides|faults|commands|alarms|stats|export` against the real binary on a store
// written through the real Store: newest first, --limit, --since in every form (and exit 2 with
// the option and value named for a bad one), --format table|json|csv, hostile strings from the
// store that must not break a table row, and inspection that leaves the store file untouched.
// Also `fleetgw status --format`.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/stat.h>

#include "storage/store.h"
#include "tests/config/cli_test_util.h"
#include "tests/config/store_fixture.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::db_cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::int64_t kSec = 1'000'000;
constexpr std::int64_t kT0 = 1732701600LL * kSec;  // 2024-11-27T10:00:00Z
const std::string kHostileName = "evil\nfault\x1b[2J";
const std::string kHostileReason = "lock_failed: \"jammed\", said\r\nline two";
const std::string kHostileDetail = "detail\twith\nnewline";

storage::RideRow ride(const std::string& id, std::int64_t start, double km) {
  return closed_ride(id, start, km);
}

// A store with 3 rides (9:00, 10:00, 11:00 on 2024-11-27), a raised and a cleared fault,
// 3 commands (one still executing, one with a hostile reason, one whose journal entry was
// purged) and 2 alarms. Strings from the network or the bus carry control characters.
void make_store(const fs::path& path) {
  storage::StoreOptions o;
  o.path = path.string();
  storage::Store store(o);
  storage::Batch b;
  b.now_us = kT0;
  b.rides.push_back({ride("ride-0900", kT0 - 3600 * kSec, 5.25), std::nullopt});
  b.rides.push_back({ride("ride-1000", kT0, 8.1), std::nullopt});
  b.rides.push_back({ride("ride-1100", kT0 + 3600 * kSec, 3.0), std::nullopt});
  storage::FaultEventRow f;
  f.node = 1;  // mc
  f.bit = 3;
  f.code = 21;
  f.name = kHostileName;
  f.severity = "error";
  f.event = storage::FaultEventKind::kRaised;
  f.first_seen_us = kT0 + 60 * kSec;
  f.last_seen_us = kT0 + 60 * kSec;
  b.faults.push_back({f, std::nullopt});
  f.event = storage::FaultEventKind::kCleared;
  f.name = "overcurrent";
  f.last_seen_us = kT0 + 600 * kSec;
  f.occurrences = 3;
  b.faults.push_back({f, std::nullopt});
  b.commands.push_back({"cmd-exec", kT0 + 700 * kSec, "executing", kT0 + 760 * kSec, {}});
  b.commands.push_back({"cmd-failed", kT0 + 100 * kSec, "failed", kT0 + 160 * kSec, {}});
  b.command_results.push_back(
      {{0, "cmd-failed", kT0 + 103 * kSec, "failed", kHostileReason, "unlock_failed", 3012},
       std::nullopt});
  b.command_results.push_back(
      {{0, "cmd-old", kT0 - 7200 * kSec, "succeeded", "", "unlocked", 412}, std::nullopt});
  storage::AlarmRow a;
  a.ts_us = kT0 + 200 * kSec;
  a.first_evidence_us = kT0 + 198 * kSec;
  a.kind = "unauthorised_movement";
  a.transition = storage::AlarmTransition::kRaised;
  a.lock_node = 7;  // lock1
  a.speed_kmh = 6.5;
  a.detail = kHostileDetail;
  b.alarms.push_back({a, std::nullopt});
  a.ts_us = kT0 + 400 * kSec;
  a.transition = storage::AlarmTransition::kCleared;
  a.detail = "";
  b.alarms.push_back({a, std::nullopt});
  const auto r = store.write(b);
  ASSERT_TRUE(r.ok()) << r.status().message;
}

class DbCli : public ::testing::Test {
 protected:
  void SetUp() override { make_store(db_); }
  Result db(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "db"});
    args.insert(args.begin() + 3, {"--db", db_.string()});
    return run(args, dir_.path());
  }
  json db_json(const std::vector<std::string>& args) {
    auto all = args;
    all.insert(all.end(), {"--format", "json"});
    const Result r = db(all);
    EXPECT_EQ(r.code, 0) << r.err;
    auto doc = json::parse(r.out, nullptr, false);
    EXPECT_TRUE(doc.is_array()) << r.out;
    return doc.is_array() ? doc : json::array();
  }
  static std::vector<std::string> lines(const std::string& text) { return lines_of(text); }

  TempDir dir_{"fleetgw-db-cli"};
  fs::path db_ = dir_.path() / "fleetgw.db";
};

TEST_F(DbCli, RidesNewestFirstInHumanUnits) {
  const json rides = db_json({"rides"});
  ASSERT_EQ(rides.size(), 3u);
  EXPECT_EQ(rides[0]["ride_id"], "ride-1100");
  EXPECT_EQ(rides[1]["ride_id"], "ride-1000");
  EXPECT_EQ(rides[2]["ride_id"], "ride-0900");
  EXPECT_EQ(rides[1]["start"], "2024-11-27T10:00:00Z");
  EXPECT_EQ(rides[1]["end"], "2024-11-27T10:28:00Z");
  EXPECT_DOUBLE_EQ(rides[1]["duration_min"].get<double>(), 28.0);
  EXPECT_DOUBLE_EQ(rides[1]["distance_km"].get<double>(), 8.1);
  EXPECT_EQ(rides[1]["soc_end_pct"], 81);

  const Result table = db({"rides"});
  ASSERT_EQ(table.code, 0) << table.err;
  const auto l = lines(table.out);
  ASSERT_EQ(l.size(), 4u) << table.out;
  EXPECT_EQ(l[0].rfind("RIDE", 0), 0u) << l[0];
  EXPECT_NE(l[2].find("2024-11-27T10:00:00Z"), std::string::npos) << l[2];
  EXPECT_NE(l[2].find("8.10"), std::string::npos) << l[2];
  EXPECT_NE(l[2].find("28.0"), std::string::npos) << l[2];
  EXPECT_EQ(l[1].find("1732701600"), std::string::npos) << "no raw microseconds: " << l[1];
}

TEST_F(DbCli, LimitAndSinceInEveryForm) {
  EXPECT_EQ(db_json({"rides", "--limit", "1"}).size(), 1u);
  EXPECT_EQ(db_json({"rides", "--limit", "0"}).size(), 3u);
  EXPECT_EQ(db_json({"rides", "--since", "2024-11-27T10:00:00Z"}).size(), 2u);
  EXPECT_EQ(db_json({"rides", "--since", "2024-11-27T10:00:01Z"}).size(), 1u);
  EXPECT_EQ(db_json({"rides", "--since", "2024-11-27T10:30:00+01:00"}).size(), 2u);
  EXPECT_EQ(db_json({"rides", "--since", "2024-11-27"}).size(), 3u);
  EXPECT_EQ(db_json({"rides", "--since", "2024-11-28"}).size(), 0u);
  EXPECT_EQ(db_json({"rides", "--since", std::to_string(kT0)}).size(), 2u);
  // Relative: counted back from the wall clock (the rides are in 2024, the clock is later).
  const auto now_s = std::chrono::duration_cast<std::chrono::seconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  ASSERT_GT(now_s, kT0 / kSec + 7200) << "the machine's clock is before the test's rides";
  const auto back_s = now_s - (kT0 / kSec - 1800);  // 30 min before the 10:00 ride
  EXPECT_EQ(db_json({"rides", "--since", std::to_string(back_s) + "s"}).size(), 2u);
  EXPECT_EQ(db_json({"rides", "--since", std::to_string(back_s / 3600 + 2) + "h"}).size(), 3u);
  EXPECT_EQ(db_json({"rides", "--since", "90s"}).size(), 0u);
  EXPECT_EQ(db_json({"faults", "--since", "1h"}).size(), 0u);
  // export takes the same forms.
  const Result exp = db({"export", "--table", "rides", "--since", "2024-11-27T10:30:00Z"});
  EXPECT_EQ(exp.code, 0) << exp.err;
  EXPECT_EQ(lines(exp.out).size(), 1u) << exp.out;
  EXPECT_NE(exp.out.find("ride-1100"), std::string::npos);
  EXPECT_EQ(db({"export", "--table", "rides", "--since", "2h"}).code, 0);
}

TEST_F(DbCli, BadSinceExitsTwoNamingTheOptionAndTheValue) {
  const std::vector<std::vector<std::string>> cases = {
      {"rides", "--since", "yesterday"},
      {"faults", "--since", "2026-02-30"},
      {"export", "--table", "rides", "--since", "2024-11-27T25:00:00Z"},
      {"commands", "--since", "2h30m"},
      {"alarms", "--since", "evil\nvalue"}};
  for (const auto& args : cases) {
    const Result r = db(args);
    EXPECT_EQ(r.code, 2) << args[0] << ' ' << args.back() << ": " << r.err;
    EXPECT_NE(r.err.find("--since"), std::string::npos) << r.err;
    const std::string shown = args.back() == "evil\nvalue" ? "evil\\nvalue" : args.back();
    EXPECT_NE(r.err.find("'" + shown + "'"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  EXPECT_EQ(db({"rides", "--format", "xml"}).code, 2);
  EXPECT_EQ(db({"rides", "--limit", "-1"}).code, 2);
  EXPECT_EQ(db({"rides", "--limit", "many"}).code, 2);
  EXPECT_EQ(db({"stats", "--format", "yaml"}).code, 2);
}

TEST_F(DbCli, FaultsCommandsAlarmsShowNamesAndTimes) {
  const json faults = db_json({"faults"});
  ASSERT_EQ(faults.size(), 2u);
  EXPECT_EQ(faults[0]["event"], "cleared");  // cleared at 10:10, raised at 10:01
  EXPECT_EQ(faults[0]["time"], "2024-11-27T10:10:00Z");
  EXPECT_EQ(faults[0]["node"], "mc");
  EXPECT_EQ(faults[0]["occurrences"], 3);
  EXPECT_EQ(faults[1]["fault"], kHostileName);

  const json commands = db_json({"commands"});
  ASSERT_EQ(commands.size(), 3u);
  EXPECT_EQ(commands[0]["command_id"], "cmd-exec");
  EXPECT_EQ(commands[0]["result"], "executing");
  EXPECT_EQ(commands[1]["command_id"], "cmd-failed");
  EXPECT_EQ(commands[1]["time"], "2024-11-27T10:01:40Z");  // received, not answered
  EXPECT_EQ(commands[1]["reason"], kHostileReason);
  EXPECT_EQ(commands[1]["final_state"], "unlock_failed");
  EXPECT_EQ(commands[2]["command_id"], "cmd-old");  // journal purged, result kept
  EXPECT_EQ(commands[2]["result"], "succeeded");

  const json alarms = db_json({"alarms"});
  ASSERT_EQ(alarms.size(), 2u);
  EXPECT_EQ(alarms[0]["transition"], "cleared");
  EXPECT_EQ(alarms[1]["alarm"], "unauthorised_movement");
  EXPECT_EQ(alarms[1]["lock"], "lock1");
  EXPECT_EQ(alarms[1]["detail"], kHostileDetail);
}

TEST_F(DbCli, HostileStringsNeverBreakATableRow) {
  for (const char* listing : {"faults", "commands", "alarms"}) {
    const Result r = db({listing});
    ASSERT_EQ(r.code, 0) << r.err;
    const auto l = lines(r.out);
    const std::size_t rows = listing == std::string("commands") ? 3 : 2;
    EXPECT_EQ(l.size(), rows + 1) << listing << ":\n" << r.out;
    for (const char c : r.out) {
      EXPECT_TRUE(c == '\n' || static_cast<unsigned char>(c) >= 0x20) << listing << ": " << int(c);
    }
  }
  EXPECT_NE(db({"faults"}).out.find("evil\\nfault\\x1b[2J"), std::string::npos);
  EXPECT_NE(db({"commands"}).out.find("said\\r\\nline two"), std::string::npos);
  EXPECT_NE(db({"alarms"}).out.find("detail\\twith\\nnewline"), std::string::npos);
}

TEST_F(DbCli, CsvIsRfc4180AndKeepsTheStoredString) {
  const Result r = db({"commands", "--format", "csv"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("time,command_id,result,reason,final_state,duration_ms\r\n", 0), 0u)
      << r.out;
  // The hostile reason, quoted, its quotes doubled, its CR LF kept inside the quotes.
  EXPECT_NE(r.out.find("\"lock_failed: \"\"jammed\"\", said\r\nline two\""), std::string::npos)
      << r.out;
  // Every record ends in CRLF; no bare LF outside the quoted field.
  std::size_t bare_lf = 0;
  for (std::size_t i = 0; i < r.out.size(); ++i) {
    if (r.out[i] == '\n' && (i == 0 || r.out[i - 1] != '\r')) ++bare_lf;
  }
  EXPECT_EQ(bare_lf, 0u);
  const Result rides = db({"rides", "--format", "csv", "--limit", "1"});
  EXPECT_EQ(lines(rides.out).size(), 2u) << rides.out;
  EXPECT_NE(rides.out.find("ride-1100,2024-11-27T11:00:00Z,2024-11-27T11:28:00Z,closed,false,"),
            std::string::npos)
      << rides.out;
}

TEST_F(DbCli, StatsInEachFormat) {
  const Result js = db({"stats"});  // not a terminal: JSON, as scripts expect
  ASSERT_EQ(js.code, 0) << js.err;
  const auto doc = json::parse(js.out, nullptr, false);
  ASSERT_TRUE(doc.is_object()) << js.out;
  EXPECT_EQ(doc["tables"]["rides"], 3);
  const Result csv = db({"stats", "--format", "csv"});
  EXPECT_EQ(csv.out.rfind("key,value\r\n", 0), 0u) << csv.out;
  EXPECT_NE(csv.out.find("\r\ntables.rides,3\r\n"), std::string::npos) << csv.out;
  const Result table = db({"stats", "--format", "table"});
  EXPECT_EQ(table.out.rfind("KEY", 0), 0u) << table.out;
  EXPECT_NE(table.out.find("tables.alarms"), std::string::npos) << table.out;
}

TEST_F(DbCli, InspectionLeavesTheStoreUntouched) {
  auto snapshot = [&] {
    std::vector<std::string> s;
    for (const auto& e : fs::directory_iterator(dir_.path())) {
      const auto name = e.path().filename().string();
      if (name.rfind("out.", 0) == 0 || name.rfind("err.", 0) == 0) continue;  // our captures
      struct stat st {};
      ::stat(e.path().c_str(), &st);
      s.push_back(name + " " + std::to_string(st.st_size) + " " +
                  std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec) +
                  " " + read_text_file(e.path()));
    }
    std::sort(s.begin(), s.end());
    return s;
  };
  const auto before = snapshot();
  for (const char* listing : {"rides", "faults", "commands", "alarms", "stats"}) {
    for (const char* format : {"table", "json", "csv"}) {
      EXPECT_EQ(db({listing, "--format", format}).code, 0) << listing << ' ' << format;
    }
  }
  EXPECT_EQ(snapshot(), before);
}

// Inspection while the service writes (WAL): every listing answers, in every format, and the
// service never notices (it exits 0 at the end of its bus time).
TEST(DbCliLive, ListingsWhileTheServiceWrites) {
  TempDir dir("fleetgw-db-live");
  const fs::path db = dir.path() / "fleetgw.db";
  const fs::path file = dir.path() / "fleetgw.toml";
  write_text_file(
      file,
      "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + std::string(FLEETGW_SOURCE_DIR) +
          "/config/scenarios/demo.toml\"\nspeed = 100\nlockstep = true\n[storage]\npath = \"" +
          db.string() + "\"\n[status]\nsocket = \"\"\n");
  Child service(
      {FLEETGW_BIN, "run", "--config", file.string(), "--bus-duration", "1330", "--duration", "60"},
      dir.path() / "svc.out", dir.path() / "svc.err");
  ASSERT_TRUE(wait_until([&] { return fs::exists(db); }, std::chrono::seconds(20)));
  // Until the service has created its tables the file is not a store yet (exit 2); from the
  // first answer on, every one must succeed.
  int rounds = 0;
  bool answered = false;
  while (!service.wait(std::chrono::milliseconds(1)).has_value() && rounds < 200) {
    ++rounds;
    for (const char* listing : {"rides", "faults", "commands", "alarms"}) {
      const Result r =
          run({FLEETGW_BIN, "db", listing, "--db", db.string(), "--format", "json", "--limit", "0"},
              dir.path());
      if (!answered && r.code != 0) continue;
      answered = true;
      ASSERT_EQ(r.code, 0) << listing << ": " << r.err;
      EXPECT_TRUE(json::parse(r.out, nullptr, false).is_array()) << r.out;
      // A reader that sees the service's commits must not take them for damage (the store
      // reads its counters in one snapshot) nor log into the data on stdout.
      EXPECT_EQ(r.err.find("behind outbox"), std::string::npos) << r.err;
    }
  }
  EXPECT_TRUE(answered);
  EXPECT_GT(rounds, 1);
  EXPECT_EQ(service.wait(std::chrono::seconds(60)), 0) << service.err();
  const Result rides = run({FLEETGW_BIN, "db", "rides", "--db", db.string()}, dir.path());
  EXPECT_EQ(rides.code, 0) << rides.err;
  EXPECT_EQ(lines_of(rides.out).size(), 2u) << "one ride in demo.toml:\n" << rides.out;
}

TEST(StatusFormat, CsvAndJsonFromTheRunningServiceJsonIsAnAlias) {
  TempDir dir("fleetgw-status-format");
  const fs::path sock = dir.path() / "status.sock";
  const fs::path file = dir.path() / "fleetgw.toml";
  write_text_file(
      file, "[vehicle]\nid = \"bike-fmt\"\n[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" +
                std::string(FLEETGW_SOURCE_DIR) +
                "/config/scenarios/demo.toml\"\nspeed = 1\nlockstep = true\n[storage]\npath = \"" +
                (dir.path() / "fleetgw.db").string() + "\"\n[status]\nsocket = \"" + sock.string() +
                "\"\n");
  EXPECT_EQ(run({FLEETGW_BIN, "status", "--json", "--format", "csv"}, dir.path()).code, 2);
  EXPECT_EQ(run({FLEETGW_BIN, "status", "--format", "xml"}, dir.path()).code, 2);
  Child service({FLEETGW_BIN, "run", "--config", file.string(), "--duration", "60"},
                dir.path() / "svc.out", dir.path() / "svc.err");
  Result csv;
  ASSERT_TRUE(wait_until(
      [&] {
        csv =
            run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "csv"}, dir.path());
        return csv.code != 3;
      },
      std::chrono::seconds(20)))
      << service.err();
  EXPECT_TRUE(csv.code == 0 || csv.code == 1) << csv.err;
  EXPECT_EQ(csv.out.rfind("key,value\r\n", 0), 0u) << csv.out;
  EXPECT_NE(csv.out.find("\r\nvehicle_id,bike-fmt\r\n"), std::string::npos) << csv.out;
  const Result js =
      run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "json"}, dir.path());
  const Result alias =
      run({FLEETGW_BIN, "status", "--config", file.string(), "--json"}, dir.path());
  for (const Result* r : {&js, &alias}) {
    const auto doc = json::parse(r->out, nullptr, false);
    ASSERT_TRUE(doc.is_object()) << r->out;
    EXPECT_EQ(doc["vehicle_id"], "bike-fmt");
  }
  const Result table =
      run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "table"}, dir.path());
  EXPECT_TRUE(json::parse(table.out, nullptr, false).is_discarded()) << "the summary, not JSON";
  service.signal(SIGTERM);
  EXPECT_EQ(service.wait(std::chrono::seconds(20)), 0) << service.err();
}

}  // namespace
}  // namespace fleetgw::testing::db_cli
