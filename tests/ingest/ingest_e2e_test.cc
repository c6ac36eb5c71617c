// `fleetgw ingest` end to end, every component real: `fleetgw run` gateways on the simulator
// publish through a real mosquitto (MQTT 5 shared subscription) to two `fleetgw ingest` workers
// writing into a real PostgreSQL (a private cluster). One worker is SIGKILLed mid-run and
// restarted: every record the gateways created lands exactly once and the gap report is empty.
// A wiped store (new store_id) does not collide with the vehicle's earlier rows; a malformed
// payload is counted and stored as rejected, not fatal; a database outage holds messages
// unacknowledged until it ends. Every wait is for a condition.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "backend/common/pg.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::PgConnection;
using fleetgw::testing::ChildProcess;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::PostgresCluster;
using fleetgw::testing::query_text;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

// Small telemetry batches at 20x: many messages in a few seconds, all at QoS 1.
fs::path write_gateway_config(const TempDir& dir, const std::string& vehicle,
                              const std::string& broker_uri) {
  std::ostringstream c;
  c << "[vehicle]\nid = \"" << vehicle << "\"\n[log]\nlevel = \"warn\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/ride.toml\"\nspeed = 20\n"
    << "[storage]\npath = \"" << (dir.path() / (vehicle + ".db")).string() << "\"\n"
    << "[status]\nsocket = \"\"\n"
    << "[mqtt]\nenabled = true\nuri = \"" << broker_uri << "\"\ntelemetry_qos = 1\n"
    << "batch_max_samples = 10\nbatch_max_ms = 500\nreconnect_min_ms = 100\n"
    << "reconnect_max_ms = 500\n";
  const fs::path path = dir.path() / (vehicle + ".toml");
  std::ofstream(path) << c.str();
  return path;
}

class IngestE2E : public ::testing::Test {
 protected:
  void SetUp() override {
    if (fleetgw::testing::postgres_bin_dir().empty()) {
      GTEST_SKIP() << "PostgreSQL server binaries not installed";
    }
    pg_ = std::make_unique<PostgresCluster>();
    broker_.start();
  }

  std::unique_ptr<ChildProcess> worker(const std::string& name) {
    auto w = std::make_unique<ChildProcess>(
        std::vector<std::string>{FLEETGW_BINARY, "ingest", "--broker", broker_.uri(), "--group",
                                 "backend", "--client-id", name, "--pg", pg_->conninfo()},
        dir_.path() / (name + ".log"));
    return w;
  }
  // Waits for the n-th "subscribed" line of a worker's log (n counts restarts: same log file).
  static bool subscribed(ChildProcess& w, std::size_t n = 1) {
    return wait_until(
               [&] {
                 const std::string log = w.log();
                 std::size_t count = 0;
                 for (std::size_t p = log.find("subscribed to"); p != std::string::npos;
                      p = log.find("subscribed to", p + 1)) {
                   ++count;
                 }
                 return count >= n || !w.running();
               },
               30s) &&
           w.running();
  }

  std::int64_t pg_count(const std::string& sql) {
    PgConnection c(pg_->conninfo());
    return c.exec(sql, "test query").int64(0, 0);
  }
  std::int64_t pg_count(const std::string& sql, const std::vector<std::string>& args) {
    PgConnection c(pg_->conninfo());
    std::vector<fleetgw::PgParam> p(args.begin(), args.end());
    return c.exec_params(sql, p, "test query").int64(0, 0);
  }

  // Sequences of (vehicle, store) accounted for in sequence_ranges.
  std::int64_t accounted(const std::string& vehicle, const std::string& store) {
    return pg_count(
        "SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges WHERE "
        "vehicle_id = $1 AND store_id = $2",
        {vehicle, store});
  }
  // Record rows of (vehicle, store) over every record table: each sequence exactly once means
  // this equals the number of records the gateway created.
  std::int64_t record_rows(const std::string& vehicle, const std::string& store) {
    std::int64_t n = 0;
    for (const char* t : {"rides", "fault_events", "telemetry_samples", "pack_snapshots",
                          "lock_events", "device_info", "alarms", "evictions"}) {
      n += pg_count(
          std::string("SELECT count(*) FROM ") + t + " WHERE vehicle_id = $1 AND store_id = $2",
          {vehicle, store});
    }
    return n + pg_count(
                   "SELECT count(*) FROM command_results WHERE vehicle_id = $1 AND "
                   "store_id = $2 AND sequence > 0",
                   {vehicle, store});
  }

  // The gateway's own account, read from its SQLite store after it stopped.
  struct StoreFacts {
    std::string store_id;
    std::int64_t created = 0;  // records 1..created
    std::int64_t unsent = 0;
  };
  static StoreFacts facts(const fs::path& db) {
    StoreFacts f;
    f.store_id = query_text(db, "SELECT value FROM meta WHERE key = 'storage.store_id'");
    f.created =
        std::stoll(query_text(db, "SELECT value FROM meta WHERE key = 'storage.next_seq'")) - 1;
    f.unsent = std::stoll(query_text(db, "SELECT count(*) FROM outbox"));
    return f;
  }

  int gaps_exit_code() {
    return fleetgw::testing::run_for_exit_code(
        {FLEETGW_BINARY, "ingest", "--gaps", "--pg", pg_->conninfo()}, dir_.path() / "gaps.log");
  }

  TempDir dir_;
  std::unique_ptr<PostgresCluster> pg_;
  MosquittoBroker broker_;
};

TEST_F(IngestE2E, KilledWorkerLosesNothingAndEveryRecordLandsOnce) {
  auto w1 = worker("worker-1");
  auto w2 = worker("worker-2");
  ASSERT_TRUE(subscribed(*w1)) << w1->log();
  ASSERT_TRUE(subscribed(*w2)) << w2->log();

  const std::vector<std::string> vehicles = {"fleet-bike-1", "fleet-bike-2", "fleet-bike-3"};
  std::vector<std::unique_ptr<GatewayProcess>> gateways;
  for (const std::string& v : vehicles) {
    gateways.push_back(std::make_unique<GatewayProcess>(
        FLEETGW_BINARY, write_gateway_config(dir_, v, broker_.uri()),
        std::vector<std::string>{"--duration", "25"}));
  }
  const std::string telemetry = "SELECT count(*) FROM telemetry_samples";
  ASSERT_TRUE(wait_until([&] { return pg_count(telemetry) >= 60; }, 60s)) << w1->log() << w2->log();
  EXPECT_EQ(w1->kill(), 128 + 9);
  // The other worker carries on alone...
  const std::int64_t at_kill = pg_count(telemetry);
  EXPECT_TRUE(wait_until([&] { return pg_count(telemetry) >= at_kill + 60; }, 60s)) << w2->log();
  // ...and the killed one comes back on its session (what the broker queued for it arrives).
  w1 = worker("worker-1");
  ASSERT_TRUE(subscribed(*w1, 2)) << w1->log();
  EXPECT_NE(w1->log().find("session resumed"), std::string::npos) << w1->log();

  for (auto& g : gateways) {
    const auto rc = g->wait_exit(90s);
    ASSERT_TRUE(rc.has_value()) << "gateway still running\n" << g->log();
    EXPECT_EQ(*rc, 0) << g->log();
  }
  for (const std::string& v : vehicles) {
    const StoreFacts f = facts(dir_.path() / (v + ".db"));
    ASSERT_FALSE(f.store_id.empty());
    ASSERT_GT(f.created, 50) << v;
    EXPECT_EQ(f.unsent, 0) << v << ": the clean stop should have drained the outbox";
    EXPECT_TRUE(wait_until([&] { return accounted(v, f.store_id) >= f.created; }, 60s))
        << v << ": " << accounted(v, f.store_id) << " of " << f.created << " accounted\n"
        << w1->log() << w2->log();
    EXPECT_EQ(accounted(v, f.store_id), f.created) << v;
    EXPECT_EQ(record_rows(v, f.store_id), f.created) << v << ": each record exactly once";
  }
  EXPECT_EQ(gaps_exit_code(), 0) << fleetgw::testing::read_text_file(dir_.path() / "gaps.log");
  EXPECT_EQ(pg_count("SELECT count(*) FROM rejected_messages"), 0);
  // Latest status per vehicle, from the retained messages.
  EXPECT_EQ(pg_count("SELECT count(*) FROM status"), 3);
  EXPECT_EQ(w1->stop(10s), 0) << w1->log();
  EXPECT_EQ(w2->stop(10s), 0) << w2->log();
  EXPECT_NE(w2->log().find("rows inserted"), std::string::npos) << w2->log();
}

// PostgreSQL goes away while messages arrive: the worker keeps them unacknowledged, retries,
// and writes them once the database is back (no restart, nothing lost, no reject).
TEST_F(IngestE2E, DatabaseOutageHoldsMessagesUntilItEnds) {
  auto w = worker("worker-outage");
  ASSERT_TRUE(subscribed(*w)) << w->log();
  pg_->stop();
  mqtt::async_client pub(broker_.uri(), "outage-publisher");
  pub.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
  for (std::uint64_t seq = 1; seq <= 5; ++seq) {
    fleetgw::v1::Envelope e;
    e.set_vehicle_id("outage-bike");
    e.set_store_id("store-1");
    e.set_sequence(seq);
    e.mutable_fault()->set_node("mc");
    e.mutable_fault()->set_name("overheat");
    pub.publish("fleet/v1/outage-bike/fault", e.SerializeAsString(), 1, false)->wait();
  }
  pub.disconnect()->wait();
  ASSERT_TRUE(wait_until([&] { return w->log_contains("stay unacknowledged"); }, 30s)) << w->log();
  pg_->start();
  EXPECT_TRUE(wait_until(
      [&] {
        try {
          // The rows and the worker's report of it: the log line follows the commit.
          return pg_count("SELECT count(*) FROM fault_events WHERE vehicle_id = 'outage-bike'") ==
                     5 &&
                 w->log_contains("writes succeed again");
        } catch (const fleetgw::PgError&) {
          return false;
        }
      },
      60s))
      << w->log();
  EXPECT_TRUE(w->log_contains("writes succeed again")) << w->log();
  EXPECT_EQ(pg_count("SELECT count(*) FROM rejected_messages"), 0);
  EXPECT_EQ(gaps_exit_code(), 0);
  EXPECT_EQ(w->stop(10s), 0) << w->log();
}

TEST_F(IngestE2E, WipedStoreAndMalformedPayload) {
  auto w = worker("worker-solo");
  ASSERT_TRUE(subscribed(*w)) << w->log();
  const std::string vehicle = "wiped-bike";
  const fs::path db = dir_.path() / (vehicle + ".db");
  const fs::path config = write_gateway_config(dir_, vehicle, broker_.uri());

  auto run_once = [&] {
    GatewayProcess g(FLEETGW_BINARY, config, {"--duration", "6"});
    const auto rc = g.wait_exit(60s);
    EXPECT_TRUE(rc.has_value() && *rc == 0) << g.log();
    return facts(db);
  };
  const StoreFacts first = run_once();

  // Hostile bytes on a record topic, and an Envelope of another vehicle on this one's topic.
  mqtt::async_client pub(broker_.uri(), "hostile-publisher");
  pub.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
  pub.publish("fleet/v1/" + vehicle + "/ride", std::string("\x0a\xff\xff\xff garbage"), 1, false)
      ->wait();
  fleetgw::v1::Envelope other;
  other.set_vehicle_id("someone-else");
  other.set_sequence(1);
  other.mutable_ride()->set_ride_id("x");
  pub.publish("fleet/v1/" + vehicle + "/ride", other.SerializeAsString(), 1, false)->wait();
  pub.disconnect()->wait();

  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(db.string() + suffix);
  const StoreFacts second = run_once();
  ASSERT_NE(first.store_id, second.store_id);

  for (const StoreFacts& f : {first, second}) {
    EXPECT_TRUE(wait_until([&] { return accounted(vehicle, f.store_id) >= f.created; }, 60s))
        << accounted(vehicle, f.store_id) << " of " << f.created << "\n"
        << w->log();
    EXPECT_EQ(record_rows(vehicle, f.store_id), f.created);
    // Both stores start at sequence 1: the same sequence numbers, distinct rows.
    EXPECT_EQ(pg_count("SELECT min(first_seq) FROM sequence_ranges WHERE vehicle_id = $1 AND "
                       "store_id = $2",
                       {vehicle, f.store_id}),
              1);
  }
  EXPECT_EQ(gaps_exit_code(), 0);
  EXPECT_EQ(pg_count("SELECT count(*) FROM rejected_messages WHERE reason LIKE 'not_an_envelope%'"),
            1);
  EXPECT_EQ(
      pg_count("SELECT count(*) FROM rejected_messages WHERE reason LIKE 'vehicle_mismatch%'"), 1);
  EXPECT_TRUE(w->running()) << w->log();
  EXPECT_EQ(w->stop(10s), 0);
  const std::string log = w->log();
  EXPECT_NE(log.find("rejected a message on fleet/v1/wiped-bike/ride"), std::string::npos) << log;
  EXPECT_NE(log.find("2 rejected (not_an_envelope=1,vehicle_mismatch=1)"), std::string::npos)
      << log;
}

}  // namespace
