// fleetgw-fleet-sim against a real mosquitto (backend/fleet_sim/fleet_sim_options.h): a few
// hundred vehicles on two event-loop processes and two loopback source addresses all connect,
// every record each vehicle counts in its report reaches a subscriber (sequence 1..last_sequence
// of every store, none missing), every publish is acknowledged; after the broker restarts the
// vehicles re-send what was not acknowledged, and what the broker routed to nobody (PUBACK 0x10),
// until every record reached the subscriber; and SIGTERM ends it within
// its stated bound while the broker acknowledges nothing.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using namespace std::chrono_literals;
using fleetgw::testing::ChildProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;

// Every (vehicle, store, sequence) published on the fleet's record topics, via a persistent
// QoS 1 session (it survives a broker restart with persistence on).
class RecordCollector {
 public:
  explicit RecordCollector(const std::string& uri)
      : client_(uri, "fleet-sim-test-collector", mqtt::create_options(MQTTVERSION_5)) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) { take(*m); });
    client_.set_connected_handler(
        [this](const std::string&) { client_.subscribe("fleet/v1/+/+", 1); });
    auto opts = mqtt::connect_options_builder()
                    .mqtt_version(MQTTVERSION_5)
                    .clean_start(false)
                    .automatic_reconnect(100ms, 1s)
                    .finalize();
    // Set on the finished options, as mqtt_connection.cc does: given to the Paho C++ 1.2
    // builder (.properties(...).finalize()) the session expiry did not take effect (measured:
    // after the broker restart its CONNACK said "session present 0", the queue was gone); set
    // here it says 1 and the queue survives.
    opts.set_properties(mqtt::properties{{mqtt::property::SESSION_EXPIRY_INTERVAL, 3600}});
    client_.connect(opts)->wait();
    client_.subscribe("fleet/v1/+/+", 1)->wait();
  }
  ~RecordCollector() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (const mqtt::exception&) {
    }
  }
  // Sequences received per store.
  std::map<std::string, std::set<std::uint64_t>> sequences() {
    std::lock_guard lock(mu_);
    return seen_;
  }
  std::size_t duplicates() {
    std::lock_guard lock(mu_);
    return duplicates_;
  }

 private:
  void take(const mqtt::message& m) {
    fleetgw::v1::Envelope e;
    if (!e.ParseFromString(m.get_payload_str())) return;
    std::lock_guard lock(mu_);
    auto& seen = seen_[e.store_id()];
    auto add = [&](std::uint64_t q) {
      if (!seen.insert(q).second) ++duplicates_;
    };
    if (e.has_telemetry()) {
      for (const auto& s : e.telemetry().samples()) add(s.sequence());
    } else if (e.sequence() != 0) {
      add(e.sequence());
    }
  }

  mqtt::async_client client_;
  std::mutex mu_;
  std::map<std::string, std::set<std::uint64_t>> seen_;
  std::size_t duplicates_ = 0;
};

// Both shard processes have started every session.
bool ramp_done(const ChildProcess& sim) {
  const std::string log = sim.log();
  std::size_t n = 0;
  for (auto p = log.find("sessions started"); p != std::string::npos;
       p = log.find("sessions started", p + 1)) {
    ++n;
  }
  return n == 2;
}

std::size_t occurrences(const std::string& text, std::string_view what) {
  std::size_t n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

nlohmann::json read_report(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in, nullptr, false);
}

std::vector<std::string> sim_args(const MosquittoBroker& broker, int vehicles, double duration_s,
                                  const std::filesystem::path& report) {
  return {FLEETGW_FLEET_SIM,
          "--vehicles",
          std::to_string(vehicles),
          "--broker",
          broker.uri(),
          "--duration-s",
          std::to_string(duration_s),
          "--riding-share",
          "1",
          "--processes",
          "2",
          "--source-addresses",
          "2",
          "--connect-rate",
          "2000",
          "--stop-timeout-s",
          "3",
          "--report",
          report.string()};
}

// The collector holds as many distinct sequences as the stores made (then expect_every_record
// says which are missing, if any).
bool all_arrived(const nlohmann::json& report, RecordCollector& collector) {
  std::uint64_t created = 0, got = 0;
  const auto seen = collector.sequences();
  for (const auto& s : report["stores"]) {
    created += s["last_sequence"].get<std::uint64_t>();
    const auto it = seen.find(s["store_id"].get<std::string>());
    if (it != seen.end()) got += it->second.size();
  }
  return got >= created;
}

// Every store's sequences 1..last_sequence, as the collector saw them.
void expect_every_record(const nlohmann::json& report, RecordCollector& collector) {
  const auto seen = collector.sequences();
  std::uint64_t missing = 0, created = 0;
  for (const auto& s : report["stores"]) {
    const auto last = s["last_sequence"].get<std::uint64_t>();
    created += last;
    const auto it = seen.find(s["store_id"].get<std::string>());
    const std::size_t got = it == seen.end() ? 0 : it->second.size();
    missing += last - std::min<std::uint64_t>(last, got);
  }
  EXPECT_GT(created, 0u);
  EXPECT_EQ(missing, 0u) << "of " << created << " records";
}

TEST(FleetSimProcess, EveryVehicleConnectsAndEveryRecordArrives) {
  MosquittoBroker broker;
  broker.start();
  RecordCollector collector(broker.uri());
  TempDir dir;
  // Riding vehicles boot within the first 30 s of the model: a third of them in 12 s.
  ChildProcess sim(sim_args(broker, 300, 12, dir.path() / "report.json"), dir.path() / "sim.log");
  const auto code = sim.wait_exit(90s);
  ASSERT_TRUE(code.has_value()) << sim.log();
  const nlohmann::json r = read_report(dir.path() / "report.json");
  ASSERT_FALSE(r.is_discarded()) << sim.log();
  EXPECT_EQ(*code, 0) << sim.log();
  EXPECT_EQ(r["connected"], 300);
  EXPECT_EQ(r["unacknowledged"], 0);
  EXPECT_EQ(r["disconnects"], 0);
  EXPECT_EQ(r["failed_processes"], 0);
  ASSERT_EQ(r["stores"].size(), 300u);
  ASSERT_TRUE(wait_until([&] { return all_arrived(r, collector); }, 20s));
  expect_every_record(r, collector);
}

TEST(FleetSimProcess, ResendsWhatWasNotAcknowledgedAfterTheBrokerRestarts) {
  MosquittoOptions options;
  options.persistence = true;  // the collector's session survives the restart
  // While the collector is away its queue grows past mosquitto's default 1,000 (then dropped).
  options.extra_config = "max_queued_messages 1000000\n";
  MosquittoBroker broker(options);
  broker.start();
  RecordCollector collector(broker.uri());
  TempDir dir;
  ChildProcess sim(sim_args(broker, 200, 20, dir.path() / "report.json"), dir.path() / "sim.log");
  ASSERT_TRUE(wait_until([&] { return ramp_done(sim); }, 30s)) << sim.log();
  ASSERT_TRUE(wait_until([&] { return !collector.sequences().empty(); }, 30s));
  // Every session accepted (the collector's and the 200 vehicles'): "sessions started" is
  // only their CONNECTs, and a session still waiting for its CONNACK when the broker goes down
  // is no lost session (under load a third of them were, and the stop below no longer gives
  // the broker a turn to answer them).
  ASSERT_TRUE(
      wait_until([&] { return occurrences(broker.log(), "New client connected") >= 201; }, 30s))
      << broker.log();
  // Frozen: publishes pile up unacknowledged; then stopped while frozen (it saves what it
  // acknowledged; a SIGKILL would lose acknowledged messages, the broker's loss, not the
  // sender's) and started again: every session is lost, what was not acknowledged must come
  // again. No resume() before stop(): it gave the broker a turn to acknowledge the whole
  // backlog before the SIGTERM, and under load it took it (nothing left to resend).
  broker.pause();
  std::this_thread::sleep_for(2s);  // no condition to wait for: nothing is acknowledged
  broker.stop();
  broker.start();
  const auto code = sim.wait_exit(120s);
  ASSERT_TRUE(code.has_value()) << sim.log();
  const nlohmann::json r = read_report(dir.path() / "report.json");
  ASSERT_FALSE(r.is_discarded()) << sim.log();
  EXPECT_EQ(r["unacknowledged"], 0) << sim.log();
  EXPECT_GE(r["disconnects"].get<int>(), 200) << sim.log();  // every session was lost once
  EXPECT_GT(r["resent"].get<int>(), 0) << sim.log();
  // Every record reaches the collector, whose session (and queue) the broker kept over the
  // restart. It used to miss ~1.5 % here (22 of 1,544): its CONNECT carried no session expiry
  // (see RecordCollector), so after the restart CONNACK said "session present 0" and what the
  // broker had queued for it was gone. Not the broker's 0x10 after a restart: mosquitto 2.0.11
  // serves a restored ordinary subscription like this one at once, only a restored shared one
  // gets nothing until a member reconnects (ingest_broker_test.cc; the fleet-sim then sends the
  // record again, `unrouted` in the report).
  ASSERT_TRUE(wait_until([&] { return all_arrived(r, collector); }, 20s))
      << "unrouted: " << r["unrouted"] << "\n"
      << sim.log();
  expect_every_record(r, collector);
}

TEST(FleetSimProcess, SigtermIsHonouredWhileTheBrokerAcknowledgesNothing) {
  MosquittoBroker broker;
  broker.start();
  TempDir dir;
  ChildProcess sim(sim_args(broker, 300, 600, dir.path() / "report.json"), dir.path() / "sim.log");
  ASSERT_TRUE(wait_until([&] { return ramp_done(sim); }, 30s)) << sim.log();
  broker.pause();
  sim.signal(SIGTERM);
  // The bound the program states: stop-timeout (3 s) + 5 s; a little slack for a loaded CI.
  const auto code = sim.wait_exit(15s);
  broker.resume();
  ASSERT_TRUE(code.has_value()) << "still running 15 s after SIGTERM\n" << sim.log();
  const nlohmann::json r = read_report(dir.path() / "report.json");
  ASSERT_FALSE(r.is_discarded()) << sim.log();
  EXPECT_EQ(r["stores"].size(), 300u);
  EXPECT_EQ(r["failed_processes"], 0);
  // What was not acknowledged is counted, and the exit status says so.
  if (r["unacknowledged"].get<int>() > 0) {
    EXPECT_EQ(*code, 1);
  }
}

}  // namespace
