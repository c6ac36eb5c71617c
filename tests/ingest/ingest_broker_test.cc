// The batched ingest through a broker restart (issue 25: "losing nothing" holds across the
// broker too, as long as it keeps its sessions): a simulated fleet (fleetgw-fleet-sim, which
// publishes again what was not acknowledged after a reconnect) → mosquitto with persistence →
// a `fleetgw ingest` worker of 4 sessions → PostgreSQL. The broker is frozen while messages
// flow (publishes and deliveries pile up unacknowledged, the worker holds a batch), stopped
// gracefully while frozen (it saves its sessions and the messages it acknowledged) and started
// again on the same port and directory. Before the freeze the worker itself is frozen for a
// few hundred messages, so the broker's session queues hold messages it has acknowledged to the
// vehicles and not yet delivered (without persistence they die with the broker: the test
// fails). Every record the fleet made must land exactly once,
// with an empty gap report: nothing the broker acknowledged to a vehicle is lost between its
// session store and the worker, and nothing delivered twice is written twice.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <csignal>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "backend/common/pg.h"
#include "tests/ingest/pg_fixture.h"
#include "tests/support/files.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

std::size_t occurrences(const std::string& text, std::string_view what) {
  std::size_t n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

// Counts the fleet's messages as the broker routes them (QoS 0, a session of its own): how far
// the traffic went while the worker was frozen.
class MessageCounter {
 public:
  explicit MessageCounter(const std::string& uri) : client_(uri, "restart-test-counter") {
    client_.set_message_callback([this](mqtt::const_message_ptr) { ++count_; });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/#", 0)->wait();
  }
  ~MessageCounter() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (const mqtt::exception&) {
    }
  }
  std::size_t count() const { return count_; }

 private:
  mqtt::async_client client_;
  std::atomic<std::size_t> count_{0};
};

// The cluster comes once per suite; each test starts from an empty database (pg_fixture.h).
class IngestBrokerRestart : public fleetgw::testing::PgDatabaseTest {
 protected:
  // -1 until the worker has made the schema.
  static std::int64_t accounted() {
    try {
      return int64("SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges");
    } catch (const fleetgw::PgError&) {
      return -1;
    }
  }
  static std::int64_t rows() {
    return int64(
        "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + "
        "(SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + "
        "(SELECT count(*) FROM device_info)");
  }

  TempDir dir_;
};

TEST_F(IngestBrokerRestart, EveryRecordLandsOnceThroughAGracefulBrokerRestart) {
  MosquittoOptions options;
  options.persistence = true;  // the sessions and their queues survive the restart
  // The worker's sessions may fall behind while the broker is frozen: no queue limit may drop.
  options.extra_config = "max_queued_messages 0\n";
  MosquittoBroker broker(options);
  broker.start();
  ChildProcess worker({FLEETGW_INGEST_BINARY, "--broker", broker.uri(), "--group", "backend",
                       "--client-id", "restart-worker", "--sessions", "4", "--batch-delay-ms", "50",
                       "--inflight", "5", "--pg", conninfo()},
                      dir_.path() / "worker.log");
  ASSERT_TRUE(wait_until([&] { return occurrences(worker.log(), "subscribed to") >= 1; }, 30s))
      << worker.log();
  const auto report = dir_.path() / "report.json";
  ChildProcess sim(
      {FLEETGW_FLEET_SIM_BINARY, "--vehicles", "200", "--broker", broker.uri(), "--duration-s",
       "20", "--riding-share", "1", "--processes", "2", "--source-addresses", "2", "--connect-rate",
       "2000", "--stop-timeout-s", "10", "--report", report.string()},
      dir_.path() / "sim.log");
  // Every vehicle connected, and records already committed: the restart falls mid-stream.
  ASSERT_TRUE(
      wait_until([&] { return occurrences(broker.log(), "New client connected") >= 4 + 200; }, 60s))
      << broker.log();
  ASSERT_TRUE(wait_until([&] { return accounted() > 0; }, 60s)) << worker.log();
  // The worker frozen: what the vehicles publish now is acknowledged to them by the broker and,
  // past the 5 messages in flight per session (--inflight: its receive maximum; the ones in
  // flight may already sit in the worker's socket buffer), waits in the worker's sessions'
  // queues in the broker only: the broker's responsibility over the restart.
  std::optional<MessageCounter> counter;
  counter.emplace(broker.uri());
  worker.signal(SIGSTOP);
  ASSERT_TRUE(wait_until([&] { return counter->count() >= 100; }, 60s)) << sim.log();
  counter.reset();
  broker.pause();
  // No condition to wait for: while frozen nothing is acknowledged, publishes pile up in the
  // vehicles' outboxes.
  std::this_thread::sleep_for(1s);
  broker.stop();
  broker.start();
  worker.signal(SIGCONT);
  const auto code = sim.wait_exit(120s);
  ASSERT_TRUE(code.has_value()) << sim.log();
  std::ifstream in(report);
  const nlohmann::json r = nlohmann::json::parse(in, nullptr, false);
  ASSERT_FALSE(r.is_discarded()) << sim.log();
  ASSERT_EQ(r["unacknowledged"], 0) << sim.log();
  EXPECT_GE(r["disconnects"].get<int>(), 200) << "every vehicle's session was lost once";
  std::int64_t expected = 0;
  for (const auto& store : r["stores"]) expected += store["last_sequence"].get<std::int64_t>();
  ASSERT_GT(expected, 0);
  EXPECT_TRUE(wait_until([&] { return accounted() >= expected; }, 60s))
      << accounted() << " of " << expected << " accounted\n"
      << worker.log();
  EXPECT_EQ(accounted(), expected);
  EXPECT_EQ(rows(), expected) << "each record exactly once";
  EXPECT_EQ(fleetgw::testing::run_for_exit_code(
                {FLEETGW_INGEST_BINARY, "--gaps", "--pg", conninfo()}, dir_.path() / "gaps.log"),
            0)
      << "gap report not empty:\n"
      << fleetgw::testing::read_text_file(dir_.path() / "gaps.log") << "\nfleet-sim:\n"
      << sim.log() << "\nbroker:\n"
      << broker.log();
  EXPECT_EQ(worker.stop(20s), 0) << worker.log();
}

}  // namespace
