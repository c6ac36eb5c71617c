// A worker leaving its group for good (issue 25, docs/backend.md "Leaving for good"), every
// component real: a publisher → mosquitto (MQTT 5 shared subscription) → two `fleetgw ingest`
// workers of one group → PostgreSQL (a private cluster).
//
// Why it needs a procedure: mosquitto 2.0 goes on giving a shared subscription's messages
// round-robin to a member whose persistent session is offline (they wait in its queue), and
// drops that queue when the session expires. A worker stopped with SIGTERM and never started
// again strands its share of the fleet's messages. `fleetgw ingest --leave` (or SIGUSR1 to a
// running worker) unsubscribes, commits what the broker still queued, and ends the sessions.
//  * Stopped, then --leave while messages flow: every message lands exactly once via the
//    remaining worker, and the broker no longer has the leaver's sessions. (With a plain
//    SIGTERM instead of the leave, the messages queued for the stopped worker never arrive:
//    the wait for them fails.)
//  * A leave SIGKILLed after a batch committed but before its acknowledgements, then the leave
//    again: every message exactly once (the redelivered ones counted as duplicates).
//  * SIGUSR1 to a running worker while messages flow: it drains, exits 0, loses nothing. A
//    leave of a client id with no session on the broker (mistyped) says so.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>

#include <chrono>
#include <csignal>
#include <memory>
#include <string>
#include <vector>

#include "backend/common/pg.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/ingest_test_util.h"
#include "tests/ingest/pg_fixture.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::ChildProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::PostgresCluster;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

constexpr const char* kVehicle = "leave-bike";

std::string fault(std::uint64_t seq) {
  return fleetgw::testing::fault_envelope(kVehicle, seq);
}

// The number before `suffix` in the last line of `log` holding it (-1: none).
long number_before(const std::string& log, const std::string& suffix) {
  const auto at = log.rfind(suffix);
  if (at == std::string::npos || at == 0) return -1;
  const auto from = log.rfind(' ', at - 1) + 1;
  return std::stol(log.substr(from, at - from));
}

class IngestLeave : public ::testing::Test {
 protected:
  void SetUp() override {
    if (fleetgw::testing::postgres_bin_dir().empty()) {
      GTEST_SKIP() << "PostgreSQL server binaries not installed";
    }
    pg_ = std::make_unique<PostgresCluster>();
    broker_.start();
    publisher_ = std::make_unique<mqtt::async_client>(broker_.uri(), "leave-publisher");
    publisher_->connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
  }
  void TearDown() override {
    if (publisher_ && publisher_->is_connected()) publisher_->disconnect()->wait();
  }

  // A worker of group "backend", 2 sessions; `extra` e.g. --leave, `env` e.g. a crash point.
  // Each name has one log for all its runs.
  std::unique_ptr<ChildProcess> worker(const std::string& name,
                                       const std::vector<std::string>& extra = {},
                                       const std::vector<std::string>& env = {}) {
    std::vector<std::string> argv{"/usr/bin/env"};
    argv.insert(argv.end(), env.begin(), env.end());
    argv.insert(argv.end(), {FLEETGW_INGEST_BINARY, "--broker", broker_.uri(), "--group", "backend",
                             "--client-id", name, "--sessions", "2", "--batch-delay-ms", "50",
                             "--pg", pg_->conninfo()});
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<ChildProcess>(argv, dir_.path() / (name + ".log"));
  }
  static bool subscribed(ChildProcess& w) {
    return wait_until([&] { return w.log_contains("subscribed to") || !w.running(); }, 30s) &&
           w.running();
  }
  // Messages first..last of kVehicle, QoS 1, each acknowledged by the broker.
  void publish(std::uint64_t first, std::uint64_t last) {
    for (std::uint64_t seq = first; seq <= last; ++seq) {
      publisher_->publish("fleet/v1/" + std::string(kVehicle) + "/fault", fault(seq), 1, false)
          ->wait();
    }
  }
  std::int64_t pg_count(const std::string& sql) {
    return fleetgw::testing::count_or_minus_one(pg_->conninfo(), sql);
  }
  std::int64_t accounted() {
    return pg_count(
        "SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges WHERE "
        "vehicle_id = '" +
        std::string(kVehicle) + "'");
  }
  std::int64_t rows() {
    return pg_count("SELECT count(*) FROM fault_events WHERE vehicle_id = '" +
                    std::string(kVehicle) + "'");
  }
  // Whether the broker still has the persistent session `client_id` (CONNACK "session
  // present"). The probe itself ends it (session expiry 0): call it once, at the end.
  bool broker_has_session(const std::string& client_id) {
    mqtt::async_client probe(broker_.uri(), client_id, mqtt::create_options(MQTTVERSION_5));
    const auto options = mqtt::connect_options_builder()
                             .mqtt_version(MQTTVERSION_5)
                             .clean_start(false)
                             .properties({{mqtt::property::SESSION_EXPIRY_INTERVAL, 0}})
                             .finalize();
    auto token = probe.connect(options);
    token->wait();
    const bool present = token->get_connect_response().is_session_present();
    probe.disconnect()->wait();
    return present;
  }
  int gaps_exit_code() {
    return fleetgw::testing::run_for_exit_code(
        {FLEETGW_INGEST_BINARY, "--gaps", "--pg", pg_->conninfo()}, dir_.path() / "gaps.log");
  }

  TempDir dir_;
  std::unique_ptr<PostgresCluster> pg_;
  MosquittoBroker broker_;
  std::unique_ptr<mqtt::async_client> publisher_;
};

TEST_F(IngestLeave, StoppedWorkerLeavesWhileMessagesFlowAndNothingIsStranded) {
  auto stay = worker("stay");
  auto go = worker("go");
  ASSERT_TRUE(subscribed(*stay)) << stay->log();
  ASSERT_TRUE(subscribed(*go)) << go->log();
  publish(1, 200);
  ASSERT_TRUE(wait_until([&] { return accounted() >= 200; }, 60s)) << stay->log() << go->log();
  ASSERT_EQ(go->stop(20s), 0) << go->log();
  // Stopped: mosquitto goes on queueing part of the group's messages for its sessions.
  publish(201, 400);
  auto leave = worker("go", {"--leave"});
  publish(401, 600);  // while it leaves
  const auto rc = leave->wait_exit(60s);
  ASSERT_TRUE(rc.has_value()) << "the leave did not end\n" << leave->log();
  EXPECT_EQ(*rc, 0) << leave->log();
  publish(601, 800);
  EXPECT_TRUE(wait_until([&] { return accounted() >= 800; }, 30s))
      << accounted() << " of 800 accounted: messages stranded with the stopped worker\n"
      << stay->log() << leave->log();
  EXPECT_EQ(rows(), 800) << "each message exactly once";
  EXPECT_EQ(gaps_exit_code(), 0);
  const std::string log = leave->log();
  EXPECT_TRUE(leave->log_contains("left group backend for good")) << log;
  // What the broker queued for the stopped worker came through the leave.
  EXPECT_GT(number_before(log, " message(s) drained"), 0) << log;
  EXPECT_FALSE(leave->log_contains("were on the broker")) << "both sessions were there\n" << log;
  EXPECT_EQ(stay->stop(20s), 0) << stay->log();
  EXPECT_FALSE(broker_has_session("go-s1"));
  EXPECT_FALSE(broker_has_session("go-s2"));
}

TEST_F(IngestLeave, LeaveKilledAfterACommitThenLeaveAgainLandsEveryMessageOnce) {
  auto stay = worker("stay");
  auto go = worker("go");
  ASSERT_TRUE(subscribed(*stay)) << stay->log();
  ASSERT_TRUE(subscribed(*go)) << go->log();
  ASSERT_EQ(go->stop(20s), 0) << go->log();
  publish(1, 400);
  // The leave's first batch commits, then SIGKILL before any acknowledgement.
  auto leave = worker("go", {"--leave"}, {"FLEETGW_INGEST_CRASH_AT=after_commit"});
  const auto killed = leave->wait_exit(60s);
  ASSERT_TRUE(killed.has_value()) << leave->log();
  EXPECT_EQ(*killed, 128 + SIGKILL) << leave->log();
  EXPECT_GT(rows(), 0);
  // The sessions are still on the broker, unsubscribed: the leave again finishes it.
  leave = worker("go", {"--leave"});
  const auto rc = leave->wait_exit(60s);
  ASSERT_TRUE(rc.has_value()) << leave->log();
  EXPECT_EQ(*rc, 0) << leave->log();
  const std::string log = leave->log();
  EXPECT_GT(number_before(log, " duplicates ignored"), 0)
      << "the committed, unacknowledged batch came again\n"
      << log;
  publish(401, 500);
  EXPECT_TRUE(wait_until([&] { return accounted() >= 500; }, 30s)) << accounted() << " of 500\n"
                                                                   << stay->log() << log;
  EXPECT_EQ(rows(), 500) << "each message exactly once";
  EXPECT_EQ(gaps_exit_code(), 0);
  EXPECT_EQ(stay->stop(20s), 0) << stay->log();
  EXPECT_FALSE(broker_has_session("go-s1"));
  EXPECT_FALSE(broker_has_session("go-s2"));
}

TEST_F(IngestLeave, RunningWorkerLeavesOnSigusr1WhileMessagesFlow) {
  auto stay = worker("stay");
  auto go = worker("go");
  ASSERT_TRUE(subscribed(*stay)) << stay->log();
  ASSERT_TRUE(subscribed(*go)) << go->log();
  publish(1, 200);
  go->signal(SIGUSR1);
  publish(201, 400);  // while it leaves
  const auto rc = go->wait_exit(60s);
  ASSERT_TRUE(rc.has_value()) << "the leave did not end\n" << go->log();
  EXPECT_EQ(*rc, 0) << go->log();
  EXPECT_TRUE(go->log_contains("left group backend for good")) << go->log();
  publish(401, 600);
  EXPECT_TRUE(wait_until([&] { return accounted() >= 600; }, 30s)) << accounted() << " of 600\n"
                                                                   << stay->log() << go->log();
  EXPECT_EQ(rows(), 600) << "each message exactly once";
  EXPECT_EQ(gaps_exit_code(), 0);
  // A leave of a client id that has no session (mistyped) says so.
  auto typo = worker("og", {"--leave"});
  const auto typo_rc = typo->wait_exit(30s);
  ASSERT_TRUE(typo_rc.has_value()) << typo->log();
  EXPECT_EQ(*typo_rc, 0) << typo->log();
  EXPECT_TRUE(typo->log_contains("only 0 of the 2 sessions og-s1..s2 were on the broker"))
      << typo->log();
  EXPECT_EQ(stay->stop(20s), 0) << stay->log();
  EXPECT_FALSE(broker_has_session("go-s1"));
  EXPECT_FALSE(broker_has_session("go-s2"));
}

}  // namespace
