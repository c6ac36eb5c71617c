// Technician tools: export of every table as JSON objects, the since filter, rejection of unknown
// tables, and stats().
#include <gtest/gtest.h>

#include <sstream>

#include "storage/schema.h"
#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

std::vector<nlohmann::json> export_rows(Store& store, std::string_view table,
                                        std::int64_t since = 0) {
  std::vector<nlohmann::json> rows;
  const auto n =
      store.export_table(table, since, [&](const nlohmann::json& row) { rows.push_back(row); });
  EXPECT_EQ(n, rows.size());
  return rows;
}

AlarmRow alarm_at(std::int64_t t, std::string kind) {
  AlarmRow a;
  a.ts_us = t;
  a.first_evidence_us = t;
  a.kind = std::move(kind);
  return a;
}

ZoneEventRow zone_event_at(std::int64_t t, std::string transition) {
  ZoneEventRow z;
  z.ts_us = t;
  z.zone_id = "old-town";
  z.zone_name = "Old town";
  z.kind = "slow";
  z.transition = std::move(transition);
  z.bundle_version = 7;
  z.lat_deg = 52.52;
  z.lon_deg = 13.405;
  z.speed_limit_kmh = 15;
  return z;
}

void fill(Store& store) {
  for (std::int64_t t : {1'000, 2'000}) {
    Batch b;
    b.now_us = t;
    b.telemetry.push_back({telemetry_at(t), payload_of("tel")});
    b.rides.push_back({ride_named("ride-" + std::to_string(t), t, true), payload_of("ride")});
    b.faults.push_back({fault_at(t, 12), payload_of("fault")});
    b.packs.push_back({pack_at(t), payload_of("pack")});
    b.locks.push_back({lock_at(t), payload_of("lock")});
    b.command_results.push_back({command_result("c" + std::to_string(t), t), Bytes{0xde, 0xad}});
    AlarmRow alarm = alarm_at(t, "unauthorised_movement");
    alarm.first_evidence_us = t - 500;
    alarm.lock_node = 8;
    alarm.speed_kmh = 12.5;
    alarm.detail = "wheel turning while frame lock locked";
    b.alarms.push_back({alarm, payload_of("alarm")});
    b.zone_events.push_back({zone_event_at(t, t == 1'000 ? "enter" : "exit"), payload_of("zone")});
    b.commands.push_back({"c" + std::to_string(t), t, "done", t + 60'000'000});
    b.meta.emplace_back("vin" + std::to_string(t), "BIKE");
    store.write(b);
  }
}

TEST(Export, EveryTableExportsTypedRows) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  fill(store);
  for (auto table : Store::exportable_tables()) {
    auto rows = export_rows(store, table);
    if (table == "eviction_counters") {
      EXPECT_EQ(rows.size(), 3u);
    } else if (table == "meta") {
      EXPECT_EQ(rows.size(), 4u) << "two vins, the sequence counter and the store id";
    } else if (table == "outbox") {
      EXPECT_EQ(rows.size(), 16u);
    } else {
      EXPECT_EQ(rows.size(), 2u) << table;
    }
    for (const auto& row : rows) EXPECT_TRUE(row.is_object()) << table;
  }
  auto tel = export_rows(store, "telemetry");
  EXPECT_EQ(tel[0]["ts_us"], 1000);
  EXPECT_DOUBLE_EQ(tel[0]["speed_kmh"].get<double>(), 21.5);
  EXPECT_EQ(tel[0]["battery_lock_state"], 1);

  auto rides = export_rows(store, "rides");
  EXPECT_EQ(rides[1]["ride_id"], "ride-2000");
  EXPECT_EQ(rides[1]["state"], "closed");
  EXPECT_DOUBLE_EQ(rides[1]["assist_time_json"]["tour"].get<double>(), 340.0)
      << "JSON columns are embedded, not quoted";

  auto packs = export_rows(store, "pack_snapshots");
  EXPECT_EQ(packs[0]["temps_json"], nlohmann::json::parse("[23.0, 24.5, 25.0]"));
  EXPECT_DOUBLE_EQ(packs[0]["lifetime_json"]["charge_ah"].get<double>(), 1234.5);

  auto faults = export_rows(store, "fault_events");
  EXPECT_EQ(faults[0]["event"], "raised");
  EXPECT_EQ(faults[0]["code"], 12);

  auto outbox = export_rows(store, "outbox");
  bool saw_blob = false;
  for (const auto& row : outbox) {
    if (row["kind"] == "command_result") {
      EXPECT_EQ(row["payload"], "dead");
      saw_blob = true;
    }
  }
  EXPECT_TRUE(saw_blob);
  auto locks = export_rows(store, "lock_events");
  EXPECT_EQ(locks[0]["new_state"], "locked");
  auto results = export_rows(store, "command_results");
  EXPECT_EQ(results[0]["duration_ms"], 850);
  auto alarms = export_rows(store, "alarms");
  EXPECT_EQ(alarms[1]["kind"], "unauthorised_movement");
  EXPECT_EQ(alarms[1]["transition"], "raised");
  EXPECT_EQ(alarms[1]["first_evidence_us"], 1500);
  EXPECT_EQ(alarms[1]["lock_node"], 8);
  EXPECT_DOUBLE_EQ(alarms[1]["speed_kmh"].get<double>(), 12.5);
  EXPECT_TRUE(alarms[1]["soc_pct"].is_null()) << "evidence that does not apply stays NULL";
  auto zones = export_rows(store, "zone_events");
  EXPECT_EQ(zones[0]["zone_id"], "old-town");
  EXPECT_EQ(zones[0]["transition"], "enter");
  EXPECT_EQ(zones[1]["transition"], "exit");
  EXPECT_EQ(zones[0]["bundle_version"], 7);
  EXPECT_EQ(zones[0]["speed_limit_kmh"], 15);
  EXPECT_DOUBLE_EQ(zones[0]["lat_deg"].get<double>(), 52.52);
}

// Zone events are queued as kind "zone" at priority 1, pointing at their row; a half position
// or an empty zone id is refused by name before anything is written.
TEST(Export, ZoneEventsAreQueuedAsZoneAndValidated) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  Batch b;
  b.now_us = 5'000;
  b.zone_events.push_back({zone_event_at(5'000, "enter"), payload_of("zone")});
  ASSERT_TRUE(store.write(b).ok());
  const auto entries = store.peek_outbox(100, 1 << 20);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].kind, OutboxKind::kZone);
  EXPECT_EQ(to_string(entries[0].kind), "zone");
  EXPECT_EQ(outbox_kind_from_string("zone"), OutboxKind::kZone);
  EXPECT_EQ(entries[0].priority, 1);
  EXPECT_TRUE(entries[0].source_id.has_value());

  Batch half;
  half.now_us = 6'000;
  auto z = zone_event_at(6'000, "exit");
  z.lon_deg.reset();
  half.zone_events.push_back({z, payload_of("zone")});
  const auto r = store.write(half);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message.find("zone_events[0].lat_deg"), std::string::npos) << r.status().message;
  Batch unnamed;
  unnamed.now_us = 6'000;
  auto u = zone_event_at(6'000, "exit");
  u.zone_id.clear();
  unnamed.zone_events.push_back({u, payload_of("zone")});
  const auto r2 = store.write(unnamed);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.status().message.find("zone_events[0].zone_id: empty"), std::string::npos)
      << r2.status().message;
  EXPECT_EQ(export_rows(store, "zone_events").size(), 1u) << "refused batches wrote nothing";
}

// An alarm stored after a backlog of faults and telemetry still leaves first: priority 0.
TEST(Export, AlarmsLeaveTheOutboxBeforeFaults) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  fill(store);
  Batch b;
  b.now_us = 3'000;
  b.faults.push_back({fault_at(3'000, 12), payload_of("fault")});
  b.alarms.push_back({alarm_at(3'000, "lock_forced"), payload_of("alarm")});
  ASSERT_TRUE(store.write(b).ok());
  const auto entries = store.peek_outbox(100, 1 << 20);
  ASSERT_FALSE(entries.empty());
  std::size_t first_fault = entries.size();
  std::size_t last_alarm = 0;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (entries[i].kind == OutboxKind::kFault) first_fault = std::min(first_fault, i);
    if (entries[i].kind == OutboxKind::kAlarm) last_alarm = i;
  }
  EXPECT_EQ(entries[last_alarm].priority, 0);
  EXPECT_LT(last_alarm, first_fault) << "every alarm precedes every fault";
  EXPECT_EQ(to_string(entries[last_alarm].kind), "alarm");
}

TEST(Export, SinceFiltersByTimeColumn) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  fill(store);
  for (std::string_view table :
       {"telemetry", "rides", "fault_events", "pack_snapshots", "lock_events", "alarms",
        "zone_events", "command_results", "commands", "outbox"}) {
    auto rows = export_rows(store, table, 1'500);
    EXPECT_EQ(rows.size(), table == "outbox" ? 8u : 1u) << table;
  }
  EXPECT_EQ(export_rows(store, "meta", 1'500).size(), 4u) << "no time column: since ignored";
}

TEST(Export, JsonLinesToStream) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  fill(store);
  std::ostringstream out;
  EXPECT_EQ(store.export_table("lock_events", 0, out), 2u);
  std::istringstream in(out.str());
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) {
    EXPECT_EQ(nlohmann::json::parse(line)["kind"], "wheel");
    ++lines;
  }
  EXPECT_EQ(lines, 2);
}

TEST(Export, UnknownTableRejectedWithKnownList) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("e.db")});
  for (std::string_view bad : {"sqlite_master", "telemetry; DROP TABLE rides", "", "Rides"}) {
    try {
      store.export_table(bad, 0, [](const nlohmann::json&) { FAIL() << "no rows expected"; });
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("unknown table '" + std::string(bad) + "'"), std::string::npos) << msg;
      EXPECT_NE(msg.find("telemetry"), std::string::npos) << msg;
    }
  }
  EXPECT_EQ(export_rows(store, "rides").size(), 0u);
}

TEST(Stats, ReportsCountsDepthFileAndCounters) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("s.db"), .max_bytes = 50 << 20});
  fill(store);
  store.peek_outbox(2, 1 << 20);
  auto s = store.stats();
  EXPECT_EQ(s.schema_version, kSchemaVersion);
  std::map<std::string, std::uint64_t> rows(s.table_rows.begin(), s.table_rows.end());
  EXPECT_EQ(rows["telemetry"], 2u);
  EXPECT_EQ(rows["outbox"], 16u);
  EXPECT_EQ(rows["alarms"], 2u);
  EXPECT_EQ(rows["zone_events"], 2u);
  ASSERT_EQ(s.outbox.size(), 6u);
  EXPECT_EQ(s.outbox[0].priority, 0);
  EXPECT_EQ(s.outbox[0].entries, 4u) << "two command results and two alarms";
  EXPECT_EQ(s.outbox[0].payload_bytes, 14u);
  EXPECT_EQ(s.outbox_in_flight, 2u);
  EXPECT_EQ(s.oldest_unsent_seq, 1u);
  EXPECT_EQ(s.oldest_unsent_us, 1'000);
  EXPECT_EQ(s.oldest_unsent_kind, "telemetry");
  EXPECT_GT(s.file_bytes + s.wal_bytes, 0u);
  EXPECT_EQ(s.page_size, 4096u);
  EXPECT_EQ(s.live_bytes, (s.page_count - s.freelist_pages) * s.page_size);
  EXPECT_EQ(s.budget_bytes, 50u << 20);
  EXPECT_EQ(s.next_seq, 17u);
  EXPECT_EQ(s.evictions.size(), 3u);
  auto j = s.to_json();
  EXPECT_EQ(j["tables"]["rides"], 2);
  EXPECT_EQ(j["outbox"]["by_priority"][5]["entries"], 2);
  EXPECT_EQ(j["evictions"]["telemetry"]["rows"], 0);
}

}  // namespace
}  // namespace fleetgw::storage
