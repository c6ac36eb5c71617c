// Schema v1.1 through the real `fleetgw run` (simulated bike) and a real mosquitto, decoded as a
// backend would: DeviceInfo on `info` at start (the gateway's own node, then the bus nodes'
// models and firmware), bus_state in the retained status, a store id in every record envelope
// that survives a restart and changes with a wiped store, and a clean stop that drains the last
// telemetry batch although its batch delay is far away. No fixed sleeps: every wait is for a
// condition with a deadline.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/sqlite_query.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;
namespace v1 = fleetgw::v1;

const std::string kVehicle = "schema11-bike";

// The bundled demo at 5x: model info and the bus within seconds. A telemetry batch delay of 10
// minutes and room for 10,000 samples: only the clean stop's drain can send the batch.
std::string write_config(const TempDir& dir, const std::string& broker_uri) {
  std::ostringstream c;
  c << "[vehicle]\nid = \"" << kVehicle << "\"\n[log]\nlevel = \"warn\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/demo.toml\"\nspeed = 5\nlockstep = true\n"
    << "[storage]\npath = \"" << (dir.path() / "fleetgw.db").string() << "\"\n"
    << "[node]\nmodel = \"SCHEMA11-IOT\"\n"
    << "[mqtt]\nenabled = true\nuri = \"" << broker_uri << "\"\ntelemetry_qos = 1\n"
    << "batch_max_ms = 600000\nbatch_max_samples = 10000\nreconnect_min_ms = 100\nreconnect_max_ms "
       "= 500\n";
  const std::string path = (dir.path() / "fleetgw.toml").string();
  std::ofstream(path) << c.str();
  return path;
}

// Everything the broker delivers on the vehicle's topics, decoded.
class Subscriber {
 public:
  explicit Subscriber(const std::string& uri)
      : client_(uri, "schema11-sub-" + std::to_string(getpid())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      v1::Envelope e;
      std::lock_guard lock(mutex_);
      if (!e.ParseFromString(m->get_payload())) {
        ++undecodable_;
        return;
      }
      envelopes_.push_back(std::move(e));
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + kVehicle + "/#", 1)->wait();
  }
  ~Subscriber() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {
    }
  }
  std::vector<v1::Envelope> envelopes() {
    std::lock_guard lock(mutex_);
    return envelopes_;
  }
  int undecodable() {
    std::lock_guard lock(mutex_);
    return undecodable_;
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::vector<v1::Envelope> envelopes_;
  int undecodable_ = 0;
};

// Reads one value from the store with SQLite itself ("" when absent), independent of the store.
std::string sql_text(const std::filesystem::path& db_path, const std::string& sql) {
  return fleetgw::testing::query_text(db_path, sql);
}

bool has_node(const v1::DeviceInfo& info, const std::string& node) {
  for (const auto& n : info.nodes()) {
    if (n.node() == node) return true;
  }
  return false;
}

struct RunResult {
  std::string store_id;            // from every record envelope (all equal)
  std::set<std::string> ids_seen;  // distinct store ids of record envelopes
  std::uint64_t min_sequence = 0;  // lowest record sequence delivered
  std::size_t telemetry_samples = 0;
  std::size_t records = 0;
};

// One run: start, wait until the backend has seen what the schema promises, SIGTERM (a clean
// stop), then check the outbox was drained.
RunResult run_once(const TempDir& dir, MosquittoBroker& broker, bool check_info) {
  Subscriber sub(broker.uri());
  GatewayProcess gw(FLEETGW_BINARY, write_config(dir, broker.uri()), {"--duration", "120"});
  auto has = [&](auto pred) {
    for (const auto& e : sub.envelopes()) {
      if (pred(e)) return true;
    }
    return false;
  };
  const auto active_online = [](const v1::Envelope& e) {
    return e.has_status() && e.status().state() == v1::ONLINE_STATE_ONLINE &&
           e.status().bus_state() == v1::BUS_STATE_ACTIVE;
  };
  const auto info_with_mc = [](const v1::Envelope& e) {
    return e.has_info() && has_node(e.info(), "mc") && has_node(e.info(), "bms");
  };
  const auto telemetry = [](const v1::Envelope& e) { return e.has_telemetry(); };
  EXPECT_TRUE(wait_until([&] { return has(active_online); }, 60s))
      << "no retained ONLINE status with bus_state ACTIVE\n"
      << gw.log();
  if (check_info) {
    EXPECT_TRUE(wait_until([&] { return has(info_with_mc); }, 60s))
        << "no DeviceInfo naming the MC and the BMS\n"
        << gw.log();
  }
  // Some riding telemetry waits in the pending batch (the ride starts 2 s into the run).
  const auto db = dir.path() / "fleetgw.db";
  EXPECT_TRUE(wait_until(
      [&] {
        const std::string n = sql_text(db, "SELECT count(*) FROM outbox WHERE kind = 'telemetry'");
        return !n.empty() && std::stoi(n) >= 10;
      },
      60s))
      << gw.log();
  EXPECT_FALSE(has(telemetry)) << "telemetry left before the batch delay: the drain is not tested";
  EXPECT_EQ(gw.stop(20s), 0) << gw.log();
  // A clean stop with the broker up leaves nothing behind, the last batch included.
  EXPECT_EQ(sql_text(db, "SELECT count(*) FROM outbox"), "0") << gw.log();
  EXPECT_TRUE(wait_until([&] { return has(telemetry); }, 10s)) << "last batch never arrived";
  std::size_t samples = 0;
  for (const auto& e : sub.envelopes()) {
    if (e.has_telemetry()) samples += static_cast<std::size_t>(e.telemetry().samples_size());
  }
  EXPECT_GE(samples, 10u) << "the pending batch did not leave whole";

  RunResult r;
  r.store_id = sql_text(db, "SELECT value FROM meta WHERE key = 'storage.store_id'");
  EXPECT_TRUE(std::regex_match(r.store_id, std::regex("[0-9a-f]{8}-[0-9a-f]{4}-4[0-9a-f]{3}-"
                                                      "[89ab][0-9a-f]{3}-[0-9a-f]{12}")))
      << "store id '" << r.store_id << "' is not a random UUID";
  EXPECT_EQ(sub.undecodable(), 0);
  bool first = true;
  for (const auto& e : sub.envelopes()) {
    if (e.has_status()) {
      if (e.status().last_will()) ADD_FAILURE() << "a last will was published on a clean stop";
      continue;  // not a record: no sequence and no store id to check
    }
    if (e.has_state()) continue;  // the retained vehicle state: not a record either
    ++r.records;
    r.ids_seen.insert(e.store_id());
    const std::uint64_t seq =
        e.has_telemetry() ? e.telemetry().samples(0).sequence() : e.sequence();
    r.min_sequence = first ? seq : std::min(r.min_sequence, seq);
    first = false;
    if (e.has_telemetry())
      r.telemetry_samples += static_cast<std::size_t>(e.telemetry().samples_size());
    if (e.has_info() && check_info) {
      if (e.info().nodes_size() < 1) {
        ADD_FAILURE() << "empty DeviceInfo";
        continue;
      }
      EXPECT_EQ(e.info().nodes(0).node(), "iot");
      EXPECT_EQ(e.info().nodes(0).model(), "SCHEMA11-IOT");
      EXPECT_FALSE(e.info().nodes(0).fw_version().empty());
    }
  }
  for (const auto& e : sub.envelopes()) {
    if (!info_with_mc(e)) continue;
    for (const auto& n : e.info().nodes()) {
      EXPECT_FALSE(n.model().empty()) << n.node();
      EXPECT_FALSE(n.fw_version().empty()) << n.node();
    }
  }
  return r;
}

TEST(SchemaV11, DeviceInfoBusStateStoreIdAndCleanStopDrain) {
  TempDir dir("fleetgw-schema11");
  MosquittoBroker broker;
  broker.start();

  const RunResult first = run_once(dir, broker, true);
  RecordProperty("first_run_records", static_cast<int>(first.records));
  RecordProperty("first_run_telemetry_samples", static_cast<int>(first.telemetry_samples));
  RecordProperty("store_id", first.store_id);
  ASSERT_GT(first.records, 0u);
  EXPECT_GT(first.telemetry_samples, 0u);
  EXPECT_EQ(first.ids_seen, std::set<std::string>{first.store_id})
      << "every record envelope carries the store's id";
  EXPECT_EQ(first.min_sequence, 1u);

  // A restart on the same store: same id, sequences go on.
  const RunResult second = run_once(dir, broker, false);
  EXPECT_EQ(second.ids_seen, std::set<std::string>{first.store_id});
  EXPECT_GT(second.min_sequence, 1u);

  // A wiped store: sequences restart at 1 under a new id, so (vehicle, store_id, sequence)
  // never collides with the records of the first store.
  for (const auto& f : std::filesystem::directory_iterator(dir.path())) {
    if (f.path().filename().string().starts_with("fleetgw.db")) std::filesystem::remove(f.path());
  }
  const RunResult wiped = run_once(dir, broker, false);
  EXPECT_EQ(wiped.min_sequence, 1u);
  EXPECT_EQ(wiped.ids_seen, std::set<std::string>{wiped.store_id});
  EXPECT_NE(wiped.store_id, first.store_id);
}

}  // namespace
