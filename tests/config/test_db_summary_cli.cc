// `fleetgw db summary` and `fleetgw db export --format jsonl|csv` against the real binary:
// exact counts on a store written by a real simulated ride (`fleetgw run` on the simulator),
// refused commands counted by the code of their reason, --since, every format; and an export
// whose CSV and JSON lines parse back to exactly what the store holds, hostile strings included.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "storage/store.h"
#include "tests/config/cli_test_util.h"
#include "tests/config/store_fixture.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::db_summary_cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::int64_t kSec = 1'000'000;
constexpr std::int64_t kT0 = 1732701600LL * kSec;  // 2024-11-27T10:00:00Z
const std::string kHostileReason = "evil\nreason\x1b[2J: \"quoted\", detail\r\nline two";
const std::string kHostileName = "name,with \"quotes\"\nand\x1b[31m";

storage::RideRow summary_ride(const std::string& id, std::int64_t start, double km) {
  storage::RideRow r = closed_ride(id, start, km);
  r.distance_integrated_km = km + 0.5;  // not used: the ride has odometer readings
  return r;
}

storage::CommandResultRow result(const std::string& id, std::int64_t at, const std::string& result,
                                 const std::string& reason) {
  return {0, id, at, result, reason, "unlocked", 40};
}

// 2 closed rides (8.1 km, 3.0 km) and an open one without odometer (1.2 km integrated); faults
// raised twice, cleared once; 7 commands: 2 succeeded, 3 refused (2 interlock_moving, 1
// expired), 1 failed, 1 still executing; alarms: theft raised and cleared, low battery raised
// twice. Everything from 10:00 on, except the first ride and one succeeded command at 09:00.
void make_store(const fs::path& path) {
  storage::StoreOptions o;
  o.path = path.string();
  storage::Store store(o);
  storage::Batch b;
  b.now_us = kT0;
  b.rides.push_back({summary_ride("ride-0900", kT0 - 3600 * kSec, 8.1), std::nullopt});
  b.rides.push_back({summary_ride("ride-1000", kT0, 3.0), std::nullopt});
  storage::RideRow open;
  open.ride_id = "ride-1100";
  open.start_us = kT0 + 3600 * kSec;
  open.duration_s = 600;
  open.distance_integrated_km = 1.2;
  b.rides.push_back({open, std::nullopt});
  storage::FaultEventRow f;
  f.node = 1;
  f.bit = 4;
  f.code = 14;
  f.name = "over_heat_protect";
  f.severity = "critical";
  f.event = storage::FaultEventKind::kRaised;
  f.first_seen_us = f.last_seen_us = kT0 + 60 * kSec;
  b.faults.push_back({f, std::nullopt});
  f.event = storage::FaultEventKind::kCleared;
  f.last_seen_us = kT0 + 160 * kSec;
  b.faults.push_back({f, std::nullopt});
  f.node = 2;
  f.name = kHostileName;
  f.event = storage::FaultEventKind::kRaised;
  f.first_seen_us = f.last_seen_us = kT0 + 300 * kSec;
  b.faults.push_back({f, std::nullopt});
  const std::string moving = "interlock_moving: will not lock the frame lock while the bike moves";
  b.command_results.push_back({result("c-old", kT0 - 3600 * kSec, "succeeded", ""), std::nullopt});
  b.command_results.push_back({result("c-1", kT0 + 10 * kSec, "succeeded", ""), std::nullopt});
  b.command_results.push_back({result("c-2", kT0 + 20 * kSec, "rejected", moving), std::nullopt});
  b.command_results.push_back({result("c-3", kT0 + 30 * kSec, "rejected", moving), std::nullopt});
  b.command_results.push_back(
      {result("c-4", kT0 + 40 * kSec, "rejected", "expired: expires_at in the past"),
       std::nullopt});
  b.command_results.push_back(
      {result("c-5", kT0 + 50 * kSec, "failed", kHostileReason), std::nullopt});
  b.commands.push_back({"c-6", kT0 + 70 * kSec, "executing", kT0 + 130 * kSec, {}});
  storage::AlarmRow a;
  a.ts_us = kT0 + 200 * kSec;
  a.first_evidence_us = kT0 + 198 * kSec;
  a.kind = "unauthorised_movement";
  a.speed_kmh = 12.5;
  a.detail = kHostileReason;
  b.alarms.push_back({a, std::nullopt});
  a.ts_us = kT0 + 260 * kSec;
  a.transition = storage::AlarmTransition::kCleared;
  b.alarms.push_back({a, std::nullopt});
  a.kind = "low_battery";
  a.transition = storage::AlarmTransition::kRaised;
  a.detail = "";
  for (int k = 0; k < 2; ++k) {
    a.ts_us = kT0 + (400 + k) * kSec;
    b.alarms.push_back({a, std::nullopt});
  }
  const auto r = store.write(b);
  ASSERT_TRUE(r.ok()) << r.status().message;
}

// RFC 4180 records: quoted fields with doubled quotes, CR LF inside quotes kept, CR LF between
// records. Returns nullopt for input that is not valid CSV (the test then fails).
std::optional<std::vector<std::vector<std::string>>> parse_csv(const std::string& text) {
  std::vector<std::vector<std::string>> records;
  std::vector<std::string> record;
  std::string field;
  std::size_t i = 0;
  while (i < text.size()) {
    if (text[i] == '"') {
      ++i;
      while (true) {
        if (i >= text.size()) return std::nullopt;  // unterminated quote
        if (text[i] == '"') {
          if (i + 1 < text.size() && text[i + 1] == '"') {
            field += '"';
            i += 2;
            continue;
          }
          ++i;
          break;
        }
        field += text[i++];
      }
    }
    while (i < text.size() && text[i] != ',' && text[i] != '\r') {
      if (text[i] == '"' || text[i] == '\n') return std::nullopt;  // stray quote or bare LF
      field += text[i++];
    }
    record.push_back(std::move(field));
    field.clear();
    if (i < text.size() && text[i] == ',') {
      ++i;
      continue;
    }
    if (i + 1 >= text.size() || text[i + 1] != '\n') return std::nullopt;  // CR without LF
    i += 2;
    records.push_back(std::move(record));
    record.clear();
  }
  if (!record.empty()) return std::nullopt;  // last record without CR LF
  return records;
}

class DbSummaryCli : public ::testing::Test {
 protected:
  void SetUp() override { make_store(db_); }
  Result db(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "db"});
    args.insert(args.begin() + 3, {"--db", db_.string()});
    return run(args, dir_.path());
  }
  json summary_json(std::vector<std::string> extra = {}) {
    std::vector<std::string> args = {"summary", "--format", "json"};
    args.insert(args.end(), extra.begin(), extra.end());
    const Result r = db(args);
    EXPECT_EQ(r.code, 0) << r.err;
    const auto doc = json::parse(r.out, nullptr, false);
    EXPECT_TRUE(doc.is_object()) << r.out;
    return doc.is_object() ? doc : json::object();
  }

  TempDir dir_{"fleetgw-db-summary"};
  fs::path db_ = dir_.path() / "fleetgw.db";
};

TEST_F(DbSummaryCli, CountsRefusedCommandsByReasonCode) {
  const json s = summary_json();
  EXPECT_EQ(s["commands"]["count"], 7);
  EXPECT_EQ(s["commands"]["by_result"],
            (json{{"succeeded", 2}, {"rejected", 3}, {"failed", 1}, {"executing", 1}}));
  EXPECT_EQ(s["commands"]["refused_by_reason"], (json{{"interlock_moving", 2}, {"expired", 1}}));
  EXPECT_EQ(s["commands"]["failed_by_reason"], (json{{"evil\nreason\x1b[2J", 1}}));
  EXPECT_EQ(s["rides"]["count"], 3);
  EXPECT_EQ(s["rides"]["open"], 1);
  EXPECT_NEAR(s["rides"]["distance_km"].get<double>(), 8.1 + 3.0 + 1.2, 1e-9);
  EXPECT_NEAR(s["rides"]["duration_min"].get<double>(), 28 + 28 + 10, 1e-9);
  EXPECT_EQ(s["faults"]["raised"], 2);
  EXPECT_EQ(s["faults"]["cleared"], 1);
  EXPECT_EQ(s["faults"]["raised_by_fault"]["mc:over_heat_protect"], 1);
  EXPECT_EQ(s["alarms"]["raised"], 3);
  EXPECT_EQ(s["alarms"]["cleared"], 1);
  EXPECT_EQ(s["alarms"]["raised_by_kind"],
            (json{{"unauthorised_movement", 1}, {"low_battery", 2}}));
  EXPECT_EQ(s["since"], nullptr);
  EXPECT_EQ(s["summary"],
            "3 rides, 12.3 km, 66 min (1 open); 2 faults raised, 1 cleared; 7 commands: 2 "
            "succeeded, 3 refused (1 expired, 2 interlock_moving), 1 failed, 1 executing; 3 "
            "alarms (2 low battery, 1 theft)");
}

TEST_F(DbSummaryCli, TableIsTheSentenceThenOneRowPerAreaAllPrintable) {
  const Result r = db({"summary"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto l = lines_of(r.out);
  ASSERT_EQ(l.size(), 7u) << r.out;  // sentence, blank, header, 4 rows
  EXPECT_EQ(l[0].rfind("3 rides, 12.3 km, 66 min (1 open); ", 0), 0u) << l[0];
  EXPECT_TRUE(l[1].empty());
  EXPECT_EQ(l[2].rfind("WHAT", 0), 0u) << l[2];
  EXPECT_EQ(l[5].rfind("commands", 0), 0u) << l[5];
  // The hostile fault name is in the faults row, escaped, on that one line.
  EXPECT_NE(l[4].find("bms:name,with \"quotes\"\\nand\\x1b[31m"), std::string::npos) << l[4];
  for (const char c : r.out) {
    EXPECT_TRUE(c == '\n' || static_cast<unsigned char>(c) >= 0x20) << int(c);
  }
}

TEST_F(DbSummaryCli, SinceAndCsv) {
  const json s = summary_json({"--since", "2024-11-27T10:00:00Z"});
  EXPECT_EQ(s["since"], "2024-11-27T10:00:00Z");
  EXPECT_EQ(s["rides"]["count"], 2);
  EXPECT_EQ(s["commands"]["count"], 6);
  EXPECT_EQ(s["commands"]["by_result"]["succeeded"], 1);
  const json later = summary_json({"--since", "2024-11-27T12:00:00Z"});
  EXPECT_EQ(later["summary"], "no rides; no faults; no commands; no alarms");
  const Result csv = db({"summary", "--format", "csv"});
  ASSERT_EQ(csv.code, 0) << csv.err;
  EXPECT_EQ(csv.out.rfind("key,value\r\n", 0), 0u) << csv.out;
  EXPECT_NE(csv.out.find("\r\ncommands.refused_by_reason.interlock_moving,2\r\n"),
            std::string::npos)
      << csv.out;
  EXPECT_EQ(db({"summary", "--since", "yesterday"}).code, 2);
  EXPECT_EQ(db({"summary", "--format", "xml"}).code, 2);
  const Result missing =
      run({FLEETGW_BIN, "db", "summary", "--db", (dir_.path() / "nope.db").string()}, dir_.path());
  EXPECT_EQ(missing.code, 2) << missing.err;
}

TEST_F(DbSummaryCli, ExportJsonlIsTheDefaultByteForByte) {
  for (const char* table : {"rides", "fault_events", "command_results", "alarms", "meta"}) {
    const Result plain = db({"export", "--table", table});
    const Result jsonl = db({"export", "--table", table, "--format", "jsonl"});
    ASSERT_EQ(plain.code, 0) << plain.err;
    EXPECT_EQ(jsonl.code, 0) << jsonl.err;
    EXPECT_EQ(jsonl.out, plain.out) << table;
    EXPECT_EQ(jsonl.err, plain.err) << table;
    for (const auto& line : lines_of(plain.out)) {
      EXPECT_TRUE(json::parse(line, nullptr, false).is_object()) << line;
    }
  }
  const auto lines = lines_of(db({"export", "--table", "command_results"}).out);
  ASSERT_EQ(lines.size(), 6u);
  EXPECT_EQ(json::parse(lines[5])["reason"], kHostileReason);
  EXPECT_EQ(db({"export", "--table", "rides", "--format", "csvx"}).code, 2);
}

TEST_F(DbSummaryCli, ExportCsvParsesBackToTheStoredRows) {
  for (const char* table : {"rides", "fault_events", "command_results", "alarms", "commands"}) {
    const Result csv = db({"export", "--table", table, "--format", "csv"});
    ASSERT_EQ(csv.code, 0) << csv.err;
    const auto records = parse_csv(csv.out);
    ASSERT_TRUE(records.has_value()) << table << ":\n" << csv.out;
    const Result jsonl = db({"export", "--table", table});
    const auto rows = lines_of(jsonl.out);
    ASSERT_EQ(records->size(), rows.size() + 1) << table;  // header + one record per row
    const auto& header = records->front();
    for (std::size_t r = 0; r < rows.size(); ++r) {
      const json row = json::parse(rows[r]);
      const auto& record = (*records)[r + 1];
      ASSERT_EQ(record.size(), header.size()) << table << " row " << r;
      ASSERT_EQ(header.size(), row.size()) << table;
      for (std::size_t c = 0; c < header.size(); ++c) {
        const json& v = row.at(header[c]);
        if (v.is_string()) {
          EXPECT_EQ(record[c], v.get<std::string>()) << table << '.' << header[c];
        } else if (v.is_null()) {
          EXPECT_EQ(record[c], "") << table << '.' << header[c];
        } else if (v.is_number_float()) {
          EXPECT_EQ(std::stod(record[c]), v.get<double>()) << table << '.' << header[c];
        } else {
          EXPECT_EQ(json::parse(record[c]), v) << table << '.' << header[c];
        }
      }
    }
  }
  // Columns in schema order, not alphabetical.
  const auto rides = parse_csv(db({"export", "--table", "rides", "--format", "csv"}).out);
  ASSERT_TRUE(rides && !rides->empty());
  EXPECT_EQ((std::vector<std::string>(rides->front().begin(), rides->front().begin() + 4)),
            (std::vector<std::string>{"id", "ride_id", "state", "partial"}));
  // The hostile strings come back exactly.
  const Result faults = db({"export", "--table", "fault_events", "--format", "csv"});
  EXPECT_NE(faults.out.find("\"name,with \"\"quotes\"\"\nand\x1b[31m\""), std::string::npos)
      << faults.out;
  const Result since =
      db({"export", "--table", "alarms", "--format", "csv", "--since", "2024-11-27T10:04:00Z"});
  EXPECT_EQ(since.err, "3 rows\n");  // cleared 10:04:20, low battery 10:06:40 and 10:06:41
  EXPECT_EQ(parse_csv(since.out)->size(), 4u);
  const Result empty =
      db({"export", "--table", "alarms", "--format", "csv", "--since", "2024-11-28"});
  EXPECT_EQ(empty.out.find("\r\n"), empty.out.size() - 2) << "the header alone: " << empty.out;
}

// A store filled by a real simulated ride: `fleetgw run` on a scenario whose every event is
// known, then the summary's exact counts. The locks start unlocked (no alarm for a locked bike
// moving) and are locked with the key at 400 s, which ends the ride.
TEST(DbSummaryRun, ExactCountsOfARealSimulatedRide) {
  TempDir dir("fleetgw-db-summary-run");
  const fs::path db = dir.path() / "fleetgw.db";
  const fs::path scenario = dir.path() / "ride.toml";
  std::string events;
  for (int lock = 1; lock <= 5; ++lock) {
    events +=
        "[[event]]\nat_s = 400\naction = \"lock\"\nnode = \"lock" + std::to_string(lock) + "\"\n";
  }
  write_text_file(scenario,
                  "[scenario]\nduration_s = 480\nstart_utc = 2024-06-01T08:00:00Z\n"
                  "[bike]\nseed = 11\nsoc_pct = 80\nlocks_locked = false\n"
                  "[[ride]]\nduration_s = 20\nspeed_kmh = 0\n"
                  "[[ride]]\nduration_s = 300\nspeed_kmh = 20\n"
                  "[[ride]]\nduration_s = 160\nspeed_kmh = 0\n"
                  "[[event]]\nat_s = 100\naction = \"fault\"\nnode = \"mc\"\nfault = "
                  "\"over_heat_protect\"\n"
                  "[[event]]\nat_s = 160\naction = \"clear\"\nnode = \"mc\"\nfault = "
                  "\"over_heat_protect\"\n"
                  "[[event]]\nat_s = 200\naction = \"fault\"\nnode = \"mc\"\nfault = "
                  "\"speed_sensor_fault\"\n"
                  "[[event]]\nat_s = 260\naction = \"clear\"\nnode = \"mc\"\n" +
                      events);
  const fs::path config = dir.path() / "fleetgw.toml";
  write_text_file(config, "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + scenario.string() +
                              "\"\nspeed = 100\nlockstep = true\n[storage]\npath = \"" +
                              db.string() + "\"\n[status]\nsocket = \"\"\n");
  // Lock-step: a loaded machine takes longer over the 480 s of bus time but sees the same ride;
  // the wall-clock duration only ends a hung run.
  const Result service = run({FLEETGW_BIN, "run", "--config", config.string(), "--bus-duration",
                              "480", "--duration", "300"},
                             dir.path(), std::chrono::seconds(330));
  EXPECT_NE((service.out + service.err).find("stopping: bus duration reached"), std::string::npos)
      << "the run ended before the ride did\n"
      << service.out << service.err;
  ASSERT_EQ(service.code, 0) << service.err;
  const Result r =
      run({FLEETGW_BIN, "db", "summary", "--db", db.string(), "--format", "json"}, dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const json s = json::parse(r.out);
  EXPECT_EQ(s["rides"]["count"], 1) << r.out;
  EXPECT_EQ(s["rides"]["open"], 0) << r.out;
  // 300 s at 20 km/h is 1.67 km; the rider needs a few seconds to get there and to stop.
  EXPECT_GT(s["rides"]["distance_km"].get<double>(), 1.5) << r.out;
  EXPECT_LT(s["rides"]["distance_km"].get<double>(), 1.75) << r.out;
  EXPECT_EQ(s["faults"]["raised"], 2) << r.out;
  EXPECT_EQ(s["faults"]["cleared"], 2) << r.out;
  EXPECT_EQ(s["faults"]["raised_by_fault"],
            (json{{"mc:over_heat_protect", 1}, {"mc:speed_sensor_fault", 1}}))
      << r.out;
  EXPECT_EQ(s["commands"]["count"], 0) << r.out;
  EXPECT_EQ(s["alarms"]["raised"], 0) << r.out;
  const std::string sentence = s["summary"];
  EXPECT_EQ(sentence.rfind("1 ride, 1.", 0), 0u) << sentence;
  EXPECT_NE(sentence.find("; 2 faults raised, 2 cleared; no commands; no alarms"),
            std::string::npos)
      << sentence;
  // The table's first line is the same sentence.
  const Result table = run({FLEETGW_BIN, "db", "summary", "--db", db.string()}, dir.path());
  EXPECT_EQ(lines_of(table.out).at(0), sentence);
}

}  // namespace
}  // namespace fleetgw::testing::db_summary_cli
