// The fleet state the console and the city's feeds read (migration 4), against a real
// PostgreSQL: every VehicleState field in vehicle_state (locks and faults as JSON, alarms as
// names, received strings stored as sent), hostile strings refused with a reason, and
// status_history keeping each connection change once despite redeliveries. Skipped when
// PostgreSQL is absent.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <variant>

#include "backend/ingest/ingest_store.h"
#include "backend/ingest/migrations.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"

namespace {

using fleetgw::PgConnection;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::IngestStore;
using fleetgw::ingest::Reject;
using fleetgw::testing::decode_as;
using fleetgw::testing::PgDatabaseTest;
namespace v1 = fleetgw::v1;

class FleetStateTest : public PgDatabaseTest {
 protected:
  void SetUp() override {
    PgDatabaseTest::SetUp();
    if (IsSkipped()) return;
    store_ = std::make_unique<IngestStore>(conninfo());
    store_->connect();
  }

  void write(const v1::Envelope& e, const std::string& leaf) {
    auto r = decode_as(e, leaf);
    ASSERT_TRUE(std::holds_alternative<Decoded>(r)) << std::get<Reject>(r).detail;
    const Decoded& d = std::get<Decoded>(r);
    const Decoded* one[] = {&d};
    const auto result = store_->write_batch(one);
    ASSERT_FALSE(result.refused[0]) << result.refused[0]->detail;
  }

  static v1::Envelope status(std::int64_t at, v1::OnlineState online, bool will) {
    v1::Envelope e;
    e.set_vehicle_id("bike-1");
    e.set_created_at_us(at);
    e.mutable_status()->set_state(online);
    e.mutable_status()->set_last_will(will);
    e.mutable_status()->set_connection(v1::CONNECTION_STATE_CONNECTED);
    return e;
  }

  std::unique_ptr<IngestStore> store_;
};

v1::Envelope full_state() {
  v1::Envelope e;
  e.set_vehicle_id("bike-1");
  v1::VehicleState* s = e.mutable_state();
  s->set_updated_at_us(1'700'000'000'000'000);
  s->set_online(true);
  s->set_mode(v1::VEHICLE_MODE_PARKED);
  v1::VehicleLock* frame = s->add_locks();
  frame->set_node("lock");
  frame->set_kind("frame");
  frame->set_state(v1::LOCK_STATE_LOCKED);
  frame->set_state_name("locked \"tight\" \\ ünïcode\nline");
  v1::VehicleLock* battery = s->add_locks();
  battery->set_node("lock2");
  battery->set_kind("battery");
  battery->set_state(v1::LOCK_STATE_UNLOCKED);
  v1::VehicleFault* f = s->add_faults();
  f->set_node("mc");
  f->set_name("overheat");
  f->set_code(0x21);
  f->set_severity("warning");
  s->add_faults()->set_name("no code");
  s->add_active_alarms(v1::ALARM_KIND_UNSPECIFIED);
  s->add_active_alarms(static_cast<v1::AlarmKind>(1));
  s->set_speed_limit_dkmh(250);
  s->set_assist(3);
  s->set_assist_name("Tour");
  s->set_bus_state(v1::BUS_STATE_ACTIVE);
  s->mutable_position()->set_lat_e7(525'200'000);
  s->mutable_position()->set_lon_e7(134'050'000);
  s->mutable_position()->set_fixed_at_us(1'699'999'999'000'000);
  s->mutable_position()->set_horizontal_error_dm(171);
  s->mutable_position()->set_heading_ddeg(2705);
  return e;
}

TEST_F(FleetStateTest, VehicleStateStoresEveryFieldTheConsoleReads) {
  write(full_state(), "state");
  const std::string q = "SELECT %s FROM vehicle_state WHERE vehicle_id = 'bike-1'";
  auto col = [&](const std::string& expr) {
    std::string sql = q;
    sql.replace(sql.find("%s"), 2, expr);
    return text(sql);
  };
  EXPECT_EQ(col("jsonb_array_length(locks)"), "2");
  EXPECT_EQ(col("locks->0->>'node'"), "lock");
  EXPECT_EQ(col("locks->0->>'kind'"), "frame");
  EXPECT_EQ(col("locks->0->>'state'"), "LOCK_STATE_LOCKED");
  EXPECT_EQ(col("locks->0->>'state_name'"), "locked \"tight\" \\ ünïcode\nline")
      << "a received string is stored as sent";
  EXPECT_EQ(col("locks->1->>'state'"), "LOCK_STATE_UNLOCKED");
  EXPECT_EQ(col("faults->0->>'code'"), "33");
  EXPECT_EQ(col("faults->0->>'severity'"), "warning");
  EXPECT_EQ(col("faults->1->>'code'"), "<null>") << "an absent code is null, not 0";
  EXPECT_EQ(col("array_to_string(active_alarms, ',')"),
            "ALARM_KIND_UNSPECIFIED," + v1::AlarmKind_Name(static_cast<v1::AlarmKind>(1)));
  EXPECT_EQ(col("speed_limit_dkmh"), "250");
  EXPECT_EQ(col("assist"), "3");
  EXPECT_EQ(col("assist_name"), "Tour");
  EXPECT_EQ(col("bus_state"), "BUS_STATE_ACTIVE");
  EXPECT_EQ(col("lat_e7"), "525200000");
  EXPECT_EQ(col("position_fixed_at_us"), "1699999999000000");
  EXPECT_EQ(col("horizontal_error_dm"), "171");
  EXPECT_EQ(col("heading_ddeg"), "2705");

  // A state without a position, a speed limit or locks: NULLs and empty arrays, not zeros.
  v1::Envelope bare;
  bare.set_vehicle_id("bike-1");
  bare.mutable_state()->set_updated_at_us(1'700'000'000'000'001);
  write(bare, "state");
  EXPECT_EQ(col("jsonb_array_length(locks)"), "0");
  EXPECT_EQ(col("speed_limit_dkmh"), "<null>");
  EXPECT_EQ(col("lat_e7"), "<null>");
  EXPECT_EQ(col("position_fixed_at_us"), "<null>");
  EXPECT_EQ(col("heading_ddeg"), "<null>");
  EXPECT_EQ(col("bus_state"), "BUS_STATE_UNSPECIFIED");
}

TEST_F(FleetStateTest, HostileStateStringsAreRefusedWithTheField) {
  v1::Envelope e = full_state();
  e.mutable_state()->mutable_locks(0)->set_node(std::string("lo\0ck", 5));
  auto r = decode_as(e, "state");
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).code, "nul_in_text");
  EXPECT_NE(std::get<Reject>(r).detail.find("state.locks.node"), std::string::npos);

  e = full_state();
  e.mutable_state()->mutable_faults(0)->set_name(std::string(2000, 'x'));
  r = decode_as(e, "state");
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).code, "text_too_long");

  e = full_state();
  for (int i = 0; i < 300; ++i) e.mutable_state()->add_locks()->set_node("x");
  r = decode_as(e, "state");
  ASSERT_TRUE(std::holds_alternative<Reject>(r));
  EXPECT_EQ(std::get<Reject>(r).code, "too_many_entries");
}

TEST_F(FleetStateTest, StatusHistoryKeepsEachConnectionChangeOnce) {
  write(status(1'000, v1::ONLINE_STATE_ONLINE, false), "status");
  write(status(2'000, v1::ONLINE_STATE_ONLINE, false), "status");  // no change: no row
  const v1::Envelope will = status(1'500, v1::ONLINE_STATE_OFFLINE, true);
  write(will, "status");
  write(will, "status");  // a redelivered last will: no second row
  write(status(9'000, v1::ONLINE_STATE_ONLINE, false), "status");
  PgConnection c(conninfo());
  const auto r = c.exec(
      "SELECT online, last_will::text, created_at_us FROM status_history WHERE vehicle_id = "
      "'bike-1' ORDER BY id",
      "history");
  ASSERT_EQ(r.rows(), 3);
  EXPECT_EQ(r.text(0, 0), "ONLINE_STATE_ONLINE");
  EXPECT_EQ(r.text(1, 0), "ONLINE_STATE_OFFLINE");
  EXPECT_EQ(r.text(1, 1), "true");
  EXPECT_EQ(r.text(2, 0), "ONLINE_STATE_ONLINE");
  EXPECT_EQ(r.text(2, 2), "9000");
  // A last will's time is its arrival (the gateway made it at connect), others the gateway's.
  EXPECT_EQ(text("SELECT (event_at_us = received_at_us)::text FROM status_history WHERE "
                 "last_will"),
            "true");
  EXPECT_EQ(text("SELECT event_at_us FROM status_history WHERE created_at_us = 9000"), "9000");
  // The latest status is still one row per vehicle.
  EXPECT_EQ(text("SELECT count(*) FROM status"), "1");
}

// Record tables are written by COPY: a received string with a tab, newline, carriage return or
// backslash (COPY's own separators and escape) is stored as sent, and a redelivery of the same
// record (the COPY refused: the ON CONFLICT statement instead) adds nothing.
TEST_F(FleetStateTest, RecordTextWithCopySeparatorsIsStoredAsSent) {
  const std::string name = "tab\there\nnew line\r\\N back\\slash \\.";
  v1::Envelope e;
  e.set_vehicle_id("bike-1");
  e.set_store_id("store-1");
  e.set_sequence(1);
  e.mutable_fault()->set_node("mc");
  e.mutable_fault()->set_name(name);
  write(e, "fault");
  write(e, "fault");
  EXPECT_EQ(text("SELECT count(*) FROM fault_events"), "1");
  EXPECT_EQ(text("SELECT name FROM fault_events"), name);
}

// A version-3 database with a vehicle's state and status gains the new columns (NULL in the
// old row) and a status history started from the current status.
TEST_F(FleetStateTest, MigrationFourKeepsStateAndStartsHistory) {
  PgConnection c(conninfo());
  c.exec("DROP SCHEMA public CASCADE; CREATE SCHEMA public", "reset");  // SetUp's store made v4+
  migrate_up_to(3);
  c.exec(
      "INSERT INTO vehicle_state (vehicle_id, updated_at_us, online, mode) VALUES ('old-bike', 5, "
      "true, 'VEHICLE_MODE_PARKED'); INSERT INTO status (vehicle_id, created_at_us, online, "
      "connection, bus_state, firmware_version, last_will, attention) VALUES ('old-bike', 7, "
      "'ONLINE_STATE_ONLINE', 'CONNECTION_STATE_CONNECTED', 'BUS_STATE_ACTIVE', '1.0', false, "
      "'{}')",
      "old rows");
  IngestStore s(conninfo());
  EXPECT_EQ(s.connect(), static_cast<int>(fleetgw::ingest::migrations().size()) - 3);
  EXPECT_EQ(text("SELECT updated_at_us FROM vehicle_state WHERE vehicle_id = 'old-bike'"), "5");
  EXPECT_EQ(text("SELECT locks FROM vehicle_state WHERE vehicle_id = 'old-bike'"), "<null>");
  EXPECT_EQ(text("SELECT online FROM status_history WHERE vehicle_id = 'old-bike'"),
            "ONLINE_STATE_ONLINE");
}

}  // namespace
