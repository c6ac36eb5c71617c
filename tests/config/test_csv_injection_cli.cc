// CSV injection (issue 24, finding 7): strings that came from the bus or a peer (a BMS serial, a
// lock kind, a fault name, a zone name, an alarm detail, a node's model in the status document)
// start with a spreadsheet formula. Every CSV the real `fleetgw` binary writes must neutralise
// them (OWASP: a leading ' and quoted), while numbers stay numbers (-3.5 A is a number, not a
// formula).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <thread>

#include "storage/store.h"
#include "tests/config/cli_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::csv_injection_cli {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kSec = 1'000'000;
constexpr std::int64_t kT0 = 1732701600LL * kSec;  // 2024-11-27T10:00:00Z
// The payload of the finding: a DDE formula that starts a program when the CSV is opened.
const std::string kSerial = "=cmd|'/Ccalc'!A0";
const std::string kNewSerial = "+cmd|'/Ccalc'!A0";
const std::string kLockKind = "-2+3+cmd|'/Ccalc'!A0";
const std::string kFaultName = "@SUM(1+1)*cmd|'/Ccalc'!A0";
const std::string kZoneName = "\t=HYPERLINK(\"http://evil.example\",\"Old Town\")";
const std::string kDetail = "\r=1+1";

// RFC 4180 records (CRLF ends, quoted fields may hold anything).
std::vector<std::vector<std::string>> read_csv(const std::string& text) {
  std::vector<std::vector<std::string>> records(1);
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"' && field.empty()) {
      quoted = true;
    } else if (c == ',') {
      records.back().push_back(std::exchange(field, {}));
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      records.back().push_back(std::exchange(field, {}));
      records.emplace_back();
      ++i;
    } else {
      field += c;
    }
  }
  EXPECT_TRUE(records.back().empty() && field.empty()) << "last record without CRLF";
  records.pop_back();
  return records;
}

bool is_number(const std::string& cell) {
  if (cell.empty()) return false;
  char* end = nullptr;
  std::strtod(cell.c_str(), &end);
  return end == cell.c_str() + cell.size();
}

// What a spreadsheet would evaluate: a text cell starting with = + - @ TAB or CR.
void expect_no_formula(const std::string& csv, const std::string& what) {
  for (const auto& record : read_csv(csv)) {
    for (const auto& cell : record) {
      if (cell.empty() || is_number(cell)) continue;
      EXPECT_EQ(std::string_view("=+-@\t\r").find(cell[0]), std::string_view::npos)
          << what << ": live formula cell " << cell;
    }
  }
}

bool has_cell(const std::string& csv, const std::string& cell) {
  for (const auto& record : read_csv(csv)) {
    for (const auto& c : record) {
      if (c == cell) return true;
    }
  }
  return false;
}

void make_store(const fs::path& path) {
  storage::StoreOptions o;
  o.path = path.string();
  storage::Store store(o);
  storage::Batch b;
  b.now_us = kT0;
  storage::AlarmRow swap;
  swap.ts_us = kT0 + 10 * kSec;
  swap.first_evidence_us = kT0 + 10 * kSec;
  swap.kind = "battery_swapped";
  swap.old_bms_serial = kSerial;
  swap.new_bms_serial = kNewSerial;
  swap.detail = kDetail;
  b.alarms.push_back({swap, std::nullopt});
  storage::LockEventRow lock;
  lock.ts_us = kT0 + 20 * kSec;
  lock.lock_node = 7;
  lock.kind = kLockKind;
  lock.old_state = "locked";
  lock.new_state = "unlocked";
  lock.cause = "manual";
  b.locks.push_back({lock, std::nullopt});
  storage::FaultEventRow f;
  f.node = 2;  // bms
  f.bit = 1;
  f.code = 7;
  f.name = kFaultName;
  f.severity = "error";
  f.event = storage::FaultEventKind::kRaised;
  f.first_seen_us = kT0 + 30 * kSec;
  f.last_seen_us = kT0 + 30 * kSec;
  b.faults.push_back({f, std::nullopt});
  storage::ZoneEventRow z;
  z.ts_us = kT0 + 40 * kSec;
  z.zone_id = "z1";
  z.zone_name = kZoneName;
  z.kind = "slow";
  z.transition = "enter";
  z.lat_deg = -33.8688;  // southern hemisphere: a negative number, not a formula
  z.lon_deg = 151.2093;
  b.zone_events.push_back({z, std::nullopt});
  storage::TelemetryRow t;
  t.ts_us = kT0 + 50 * kSec;
  t.current_a = -3.5;  // regenerating: a negative number
  t.speed_kmh = 12.0;
  b.telemetry.push_back({t, std::nullopt});
  const auto r = store.write(b);
  ASSERT_TRUE(r.ok()) << r.status().message;
}

class CsvInjection : public ::testing::Test {
 protected:
  void SetUp() override { make_store(db_); }
  std::string csv(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "db"});
    args.insert(args.begin() + 3, {"--db", db_.string()});
    args.insert(args.end(), {"--format", "csv"});
    const Result r = run(args, dir_.path());
    EXPECT_EQ(r.code, 0) << r.err;
    return r.out;
  }
  TempDir dir_{"fleetgw-csv-injection"};
  fs::path db_ = dir_.path() / "fleetgw.db";
};

TEST_F(CsvInjection, ExportNeutralisesBusStringsAndKeepsNumbers) {
  const std::string alarms = csv({"export", "--table", "alarms"});
  expect_no_formula(alarms, "export alarms");
  EXPECT_TRUE(has_cell(alarms, "'" + kSerial)) << alarms;
  EXPECT_TRUE(has_cell(alarms, "'" + kNewSerial)) << alarms;
  EXPECT_TRUE(has_cell(alarms, "'" + kDetail)) << alarms;

  const std::string locks = csv({"export", "--table", "lock_events"});
  expect_no_formula(locks, "export lock_events");
  EXPECT_TRUE(has_cell(locks, "'" + kLockKind)) << locks;

  const std::string faults = csv({"export", "--table", "fault_events"});
  expect_no_formula(faults, "export fault_events");
  EXPECT_TRUE(has_cell(faults, "'" + kFaultName)) << faults;

  const std::string zones = csv({"export", "--table", "zone_events"});
  expect_no_formula(zones, "export zone_events");
  EXPECT_TRUE(has_cell(zones, "'" + kZoneName)) << zones;
  EXPECT_TRUE(has_cell(zones, "-33.8688")) << "a number stays a number: " << zones;

  const std::string telemetry = csv({"export", "--table", "telemetry"});
  EXPECT_TRUE(has_cell(telemetry, "-3.5")) << telemetry;
  EXPECT_FALSE(has_cell(telemetry, "'-3.5")) << telemetry;
}

TEST_F(CsvInjection, ListingsAndSummaryNeutraliseBusStrings) {
  const std::string alarms = csv({"alarms"});
  expect_no_formula(alarms, "db alarms");
  EXPECT_TRUE(has_cell(alarms, "'" + kDetail)) << alarms;

  const std::string faults = csv({"faults"});
  expect_no_formula(faults, "db faults");
  EXPECT_TRUE(has_cell(faults, "'" + kFaultName)) << faults;

  expect_no_formula(csv({"summary"}), "db summary");
  expect_no_formula(csv({"stats"}), "db stats");
}

// A listening Unix socket that answers one connection with `doc`, as the service's status
// socket does (status_server.h): the status document holds what the bus reported.
class FakeStatusSocket {
 public:
  FakeStatusSocket(const fs::path& path, std::string doc) : doc_(std::move(doc)) {
    fd_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string p = path.string();
    EXPECT_LT(p.size(), sizeof addr.sun_path);
    p.copy(addr.sun_path, sizeof addr.sun_path - 1);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    EXPECT_EQ(::listen(fd_, 1), 0);
    server_ = std::thread([this] {
      const int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0) return;
      std::string_view rest = doc_;
      while (!rest.empty()) {
        const ssize_t n = ::write(c, rest.data(), rest.size());
        if (n <= 0) break;
        rest.remove_prefix(static_cast<std::size_t>(n));
      }
      ::close(c);
    });
  }
  ~FakeStatusSocket() {
    ::shutdown(fd_, SHUT_RDWR);  // wakes accept() if nobody connected
    server_.join();
    ::close(fd_);
  }
  FakeStatusSocket(const FakeStatusSocket&) = delete;
  FakeStatusSocket& operator=(const FakeStatusSocket&) = delete;

 private:
  std::string doc_;
  int fd_ = -1;
  std::thread server_;
};

TEST(CsvInjectionStatus, StatusDocumentStringsAreNeutralised) {
  TempDir dir("fleetgw-csv-status");
  const fs::path sock = dir.path() / "status.sock";
  nlohmann::json doc = {
      {"schema", 1},
      {"vehicle_id", "bike-1"},
      {"bus", {{"transport", "sim"}, {"detail", kDetail}}},
      {"nodes", {{{"name", "bms"}, {"online", true}, {"model", kSerial}, {"firmware", kNewSerial}}}},
      {"vehicle", {{"current_a", -3.5}}}};
  FakeStatusSocket server(sock, doc.dump());
  const Result r =
      run({FLEETGW_BIN, "status", "--socket", sock.string(), "--format", "csv"}, dir.path());
  ASSERT_NE(r.code, 3) << r.err;
  expect_no_formula(r.out, "status");
  EXPECT_TRUE(has_cell(r.out, "'" + kSerial)) << r.out;
  EXPECT_TRUE(has_cell(r.out, "'" + kNewSerial)) << r.out;
  EXPECT_TRUE(has_cell(r.out, "-3.5")) << r.out;
}

}  // namespace
}  // namespace fleetgw::testing::csv_injection_cli
