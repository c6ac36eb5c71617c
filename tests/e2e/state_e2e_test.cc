// Issue 13, last-known state: the retained fleetgw.v1.VehicleState on <prefix>/<vehicle>/state
// through the real `fleetgw run` (simulated parked bike, config/scenarios/parked.toml), SQLite
// and a real mosquitto. A subscriber that arrives late -- while the gateway runs after a restart,
// and after it stopped -- gets the whole state at once from the broker (retained), and it matches
// the bike (scenario values) and the store (the last telemetry row). No fixed sleeps.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>

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

const std::string kStateVehicle = "state-bike-7";

// A late subscriber to the state topic only: what the broker hands it (retained first).
class StateSubscriber {
 public:
  StateSubscriber(const std::string& uri, const std::string& name)
      : client_(uri, name + "-" + std::to_string(getpid())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      std::lock_guard lock(mutex_);
      if (!e.ParseFromString(m->get_payload()) || !e.has_state()) return;
      last_ = e.state();
      retained_ = m->is_retained();
      ++received_;
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + kStateVehicle + "/state", 1)->wait();
  }
  ~StateSubscriber() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {
    }
  }
  std::optional<fleetgw::v1::VehicleState> last() {
    std::lock_guard lock(mutex_);
    return last_;
  }
  bool first_was_retained() {
    std::lock_guard lock(mutex_);
    return received_ > 0 && retained_;
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::optional<fleetgw::v1::VehicleState> last_;
  bool retained_ = false;
  int received_ = 0;
};

std::string sql_value(const std::filesystem::path& db_path, const std::string& sql) {
  return fleetgw::testing::query_text(db_path, sql);
}

const fleetgw::v1::VehicleLock* find_lock(const fleetgw::v1::VehicleState& s,
                                          const std::string& kind) {
  for (const auto& l : s.locks()) {
    if (l.kind() == kind) return &l;
  }
  return nullptr;
}

// parked.toml: SOC 91 %, odometer 1234.5 km, every lock locked, nothing moves.
void expect_matches_the_parked_bike(const fleetgw::v1::VehicleState& s) {
  ASSERT_TRUE(s.has_soc_pct());
  EXPECT_NEAR(s.soc_pct(), 91, 1);
  ASSERT_TRUE(s.has_odo_m());
  EXPECT_EQ(s.odo_m(), 1'234'500u);
  for (const char* kind : {"seat", "frame", "steering", "battery", "other"}) {
    const auto* l = find_lock(s, kind);
    ASSERT_NE(l, nullptr) << kind;
    EXPECT_EQ(l->state(), fleetgw::v1::LOCK_STATE_LOCKED) << kind;
    EXPECT_EQ(l->state_name(), "locked") << kind;
  }
  EXPECT_EQ(s.mode(), fleetgw::v1::VEHICLE_MODE_PARKED);
  EXPECT_TRUE(s.active_alarms().empty());
  EXPECT_FALSE(s.has_position()) << "no GNSS configured: position unknown, not 0,0";
}

TEST(StateEndToEnd, LateSubscriberGetsTheRetainedStateMatchingBikeAndStoreAcrossARestart) {
  TempDir dir("fleetgw-state-e2e");
  MosquittoBroker broker;
  broker.start();
  const auto db = dir.path() / "fleetgw.db";
  std::ostringstream c;
  c << "[vehicle]\nid = \"" << kStateVehicle << "\"\n[log]\nlevel = \"warn\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/parked.toml\"\nspeed = 10\nlockstep = true\nstart_now = false\n"
    << "[storage]\npath = \"" << db.string() << "\"\n"
    << "[mqtt]\nenabled = true\nuri = \"" << broker.uri() << "\"\nstate_interval_ms = 500\n"
    << "reconnect_min_ms = 100\nreconnect_max_ms = 500\n"
    << "[parked]\nsettle_s = 5\n";
  const std::string config = (dir.path() / "fleetgw.toml").string();
  std::ofstream(config) << c.str();

  {  // First run: 20 s of a parked bike.
    GatewayProcess first(FLEETGW_BINARY, config, {"--duration", "60", "--bus-duration", "20"});
    ASSERT_EQ(first.wait(), 0) << first.log();
  }
  {  // After a clean stop: the whole state, retained, saying offline.
    StateSubscriber late(broker.uri(), "state-late-1");
    ASSERT_TRUE(wait_until([&] { return late.last().has_value(); }, 10s));
    EXPECT_TRUE(late.first_was_retained());
    const auto s = *late.last();
    EXPECT_FALSE(s.online()) << "published by the clean stop";
    expect_matches_the_parked_bike(s);
  }

  // Restart: while the second run is up, a new subscriber sees it online again.
  GatewayProcess second(FLEETGW_BINARY, config, {"--duration", "60", "--bus-duration", "30"});
  {
    StateSubscriber during(broker.uri(), "state-late-2");
    ASSERT_TRUE(wait_until(
        [&] {
          const auto s = during.last();
          return (s && s->online() && s->mode() == fleetgw::v1::VEHICLE_MODE_PARKED) ||
                 !second.running();
        },
        30s));
    const auto s = during.last();
    ASSERT_TRUE(s && s->online()) << second.log();
    expect_matches_the_parked_bike(*s);
  }
  ASSERT_EQ(second.wait(), 0) << second.log();

  StateSubscriber after(broker.uri(), "state-late-3");
  ASSERT_TRUE(wait_until([&] { return after.last().has_value(); }, 10s));
  EXPECT_TRUE(after.first_was_retained());
  const auto s = *after.last();
  EXPECT_FALSE(s.online());
  expect_matches_the_parked_bike(s);
  // The store agrees: its newest telemetry sample has the same SOC ...
  const std::string soc =
      sql_value(db, "SELECT soc_pct FROM telemetry WHERE soc_pct IS NOT NULL ORDER BY id DESC");
  ASSERT_FALSE(soc.empty());
  EXPECT_NEAR(std::stod(soc), s.soc_pct(), 0.5);
  // ... and no alarm was ever raised, as the state's empty active_alarms says.
  EXPECT_EQ(sql_value(db, "SELECT COUNT(*) FROM alarms"), "0");
  EXPECT_GT(s.updated_at_us(), 0);
}

}  // namespace
