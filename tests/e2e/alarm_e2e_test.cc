// Issue 13, operator alarms end to end: the bundled theft scenario (config/scenarios/theft.toml:
// parked with the frame lock locked, ridden away at ~15 km/h for 60 s) through the real
// `fleetgw run` on the simulator, SQLite and a real mosquitto. The broker must see exactly one
// UNAUTHORISED_MOVEMENT alarm with its evidence, on the alarm topic, and telemetry at the riding
// rate while the locked bike moves. No fixed sleeps: every wait is for a condition.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace {

using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using namespace std::chrono_literals;

const std::string kVehicle = "alarm-bike-3";
// theft.toml has no start_utc: the simulator's virtual epoch, 2024-06-01T08:00:00Z.
constexpr int64_t kScenarioStartUs = 1'717'228'800'000'000;

int64_t offset_us(double s) {
  return kScenarioStartUs + static_cast<int64_t>(s * 1e6);
}

// Alarms (with their topic) and telemetry sample times, as a backend decodes them.
class AlarmSubscriber {
 public:
  explicit AlarmSubscriber(const std::string& uri)
      : client_(uri, "alarm-e2e-" + std::to_string(getpid())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      std::lock_guard lock(mutex_);
      if (!e.ParseFromString(m->get_payload())) return;
      if (e.has_alarm()) alarms_.push_back({m->get_topic(), e.alarm()});
      if (e.has_telemetry()) {
        for (const auto& s : e.telemetry().samples()) samples_.push_back(s.sampled_at_us());
      }
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + kVehicle + "/#", 1)->wait();
  }
  ~AlarmSubscriber() {
    try {
      client_.disconnect()->wait_for(2s);
    } catch (...) {
    }
  }
  struct Received {
    std::string topic;
    fleetgw::v1::Alarm alarm;
  };
  std::vector<Received> alarms() {
    std::lock_guard lock(mutex_);
    return alarms_;
  }
  std::vector<int64_t> samples() {
    std::lock_guard lock(mutex_);
    return samples_;
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::vector<Received> alarms_;
  std::vector<int64_t> samples_;
};

TEST(AlarmEndToEnd, TheftYieldsExactlyOneMovementAlarmOnTheBrokerAndTelemetryFlows) {
  TempDir dir("fleetgw-alarm-e2e");
  MosquittoBroker broker;
  broker.start();
  AlarmSubscriber sub(broker.uri());

  std::ostringstream c;
  c << "[vehicle]\nid = \"" << kVehicle << "\"\n[log]\nlevel = \"warn\"\n"
    << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" << FLEETGW_SOURCE_DIR
    << "/config/scenarios/theft.toml\"\nspeed = 10\nlockstep = true\n"
    << "start_now = false\n"  // bus time on the scenario's own epoch
    << "[storage]\npath = \"" << (dir.path() / "fleetgw.db").string() << "\"\n"
    << "[mqtt]\nenabled = true\nuri = \"" << broker.uri() << "\"\ntelemetry_qos = 1\n"
    << "reconnect_min_ms = 100\nreconnect_max_ms = 500\n";
  const std::string config = (dir.path() / "fleetgw.toml").string();
  std::ofstream(config) << c.str();

  // 140 s of bus time (the whole scenario) at 10x; the wall-time bound is only a safety net.
  GatewayProcess gateway(FLEETGW_BINARY, config, {"--duration", "120", "--bus-duration", "140"});
  ASSERT_EQ(gateway.wait(), 0) << gateway.log();
  // The clear is published last (30 s after the stop at 80 s); wait for it, with a deadline.
  ASSERT_TRUE(wait_until([&] { return sub.alarms().size() >= 2; }, 10s))
      << "alarms received: " << sub.alarms().size() << "\n"
      << gateway.log();

  const auto alarms = sub.alarms();
  int raised = 0;
  int cleared = 0;
  for (const auto& [topic, a] : alarms) {
    EXPECT_EQ(topic, "fleet/v1/" + kVehicle + "/alarm");
    EXPECT_EQ(a.kind(), fleetgw::v1::ALARM_KIND_UNAUTHORISED_MOVEMENT) << a.detail();
    if (a.transition() == fleetgw::v1::ALARM_TRANSITION_RAISED) ++raised;
    if (a.transition() == fleetgw::v1::ALARM_TRANSITION_CLEARED) ++cleared;
  }
  EXPECT_EQ(raised, 1) << "exactly one alarm for the theft";
  EXPECT_EQ(cleared, 1);
  const fleetgw::v1::Alarm& a = alarms.front().alarm;
  ASSERT_EQ(a.transition(), fleetgw::v1::ALARM_TRANSITION_RAISED) << "raised before cleared";
  // The wheel starts turning at 20 s of the scenario; 2 s of evidence before the alarm.
  EXPECT_GE(a.first_evidence_us(), offset_us(20));
  EXPECT_LE(a.first_evidence_us(), offset_us(23));
  EXPECT_GE(a.at_us() - a.first_evidence_us(), 2'000'000);
  EXPECT_LE(a.at_us() - a.first_evidence_us(), 2'500'000);
  ASSERT_TRUE(a.has_speed_dkmh());
  EXPECT_GT(a.speed_dkmh(), 10u) << "moving at walking pace or more";
  EXPECT_FALSE(a.detail().empty());

  // Telemetry while moving locked: the riding rate (1 Hz), not the parked one (1/min).
  ASSERT_TRUE(wait_until(
      [&] {
        int n = 0;
        for (int64_t t : sub.samples()) n += t >= offset_us(25) && t < offset_us(75);
        return n >= 45;
      },
      10s))
      << "telemetry samples received: " << sub.samples().size();
}

}  // namespace
