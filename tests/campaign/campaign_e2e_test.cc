// A campaign through the real `fleetgw run` (simulated bike) and a real mosquitto (issue 29):
// signed with `fleetgw campaign sign`, published retained on the fleet-wide topic, accepted and
// stored; a daily time window runs on the bike's clock while the broker is DOWN, and its samples
// arrive after the reconnect exactly once -- every sample inside the window, no record twice,
// as many samples as the gateway's status says it kept. A campaign for other firmware is
// accepted but never collects (not_targeted). Every wait is for a condition, and every time is
// the bike's (the status's campaigns.bus_now_us): a lock-step simulated bus slips behind the
// wall clock on a busy machine, and the windows are judged on the bus.
#include <gtest/gtest.h>
#include <mqtt/async_client.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"
#include "tests/support/zone_operator.h"

namespace {

using fleetgw::testing::GatewayConfig;
using fleetgw::testing::GatewayProcess;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using fleetgw::testing::wait_until;
using fleetgw::testing::ZoneOperator;
using namespace std::chrono_literals;

void publish_retained(const std::string& uri, const std::string& topic,
                      const std::string& payload) {
  mqtt::async_client client(uri, "campaign-publisher-" + std::to_string(getpid()));
  client.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
  client.publish(mqtt::make_message(topic, payload, 1, true))->wait();
  client.disconnect()->wait();
}

// Every campaign record the backend receives, by (store_id, sequence), and how many came twice.
class CampaignWatcher {
 public:
  CampaignWatcher(const std::string& uri, const std::string& vehicle)
      : client_(uri, "campaign-watch-" + std::to_string(getpid())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      fleetgw::v1::Envelope e;
      if (!e.ParseFromString(m->get_payload()) || !e.has_campaign()) return;
      std::lock_guard lock(mutex_);
      const auto key = e.store_id() + "/" + std::to_string(e.sequence());
      if (!records_.emplace(key, e.campaign()).second) ++duplicates_;
    });
    client_.connect(mqtt::connect_options_builder().clean_session(true).finalize())->wait();
    client_.subscribe("fleet/v1/" + vehicle + "/campaign", 1)->wait();
  }
  ~CampaignWatcher() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (...) {  // the broker may be gone already
    }
  }
  std::map<std::string, fleetgw::v1::CampaignSamples> records() {
    std::lock_guard lock(mutex_);
    return records_;
  }
  int duplicates() {
    std::lock_guard lock(mutex_);
    return duplicates_;
  }

 private:
  mqtt::async_client client_;
  std::mutex mutex_;
  std::map<std::string, fleetgw::v1::CampaignSamples> records_;
  int duplicates_ = 0;
};

nlohmann::json status_of(const TempDir& dir, const std::filesystem::path& config) {
  const auto out = dir.path() / "status.json";
  std::filesystem::remove(out);
  fleetgw::testing::run_for_exit_code(
      {FLEETGW_BINARY, "status", "--config", config.string(), "--json"}, out,
      dir.path() / "status.err");
  auto doc = nlohmann::json::parse(fleetgw::testing::read_text_file(out), nullptr, false);
  return doc.is_object() ? doc : nlohmann::json();
}

nlohmann::json campaign_status(const nlohmann::json& status, const std::string& id) {
  if (!status.is_object() || !status.contains("campaigns")) return nullptr;
  for (const auto& c : status["campaigns"]["campaigns"]) {
    if (c.value("id", "") == id) return c;
  }
  return nullptr;
}

// The bike's clock as the gateway reports it; -1 before its status answers.
std::int64_t bus_now_us(const nlohmann::json& status) {
  if (!status.is_object() || !status.contains("campaigns")) return -1;
  return status["campaigns"].value("bus_now_us", std::int64_t{-1});
}

std::int64_t day_second(std::int64_t us) {
  return (us / 1'000'000) % 86'400;
}

TEST(CampaignEndToEnd, ATimeWindowRunsOfflineAndItsSamplesArriveOnceAfterTheReconnect) {
  TempDir dir;
  MosquittoOptions options;
  options.persistence = true;  // the retained campaign survives the broker's outage
  MosquittoBroker broker(options);
  broker.start();
  const std::string vehicle = "campaign-e2e-1";
  ZoneOperator ops(dir, FLEETGW_BINARY);  // its `ops` key signs the campaigns

  // The gateway first: however long a loaded machine takes to start it, the window below is
  // chosen once it is connected, so only the signing and the retained delivery (not the
  // start-up) stand between choosing the window and stopping the broker before it opens.
  GatewayConfig c(vehicle, dir / "fleetgw.db");
  c.sim(std::string(FLEETGW_SOURCE_DIR) + "/config/scenarios/ride.toml", 1)
      .set_string("status", "socket", (dir / "status.sock").string());
  c.mqtt(broker.uri())
      .set("mqtt", "reconnect_min_ms", "100")
      .set("mqtt", "reconnect_max_ms", "500");
  c.add_line("command.trusted_keys", ops.key_line());
  const auto config = dir / "fleetgw.toml";
  c.write(config);
  GatewayProcess gw(FLEETGW_BINARY, config, {"--duration", "600"});
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("uplink: connected"); }, 60s)) << gw.log();

  // The window: 10 s of the bike's day, from 20 s of bus time from now (whole seconds of UTC).
  std::int64_t now = -1;
  ASSERT_TRUE(wait_until([&] { return (now = bus_now_us(status_of(dir, config))) > 0; }, 30s))
      << gw.log();
  const std::int64_t start = (now / 1'000'000 + 20) * 1'000'000;
  const std::int64_t end = start + 10'000'000;
  auto sign = [&](const std::string& id, const std::string& extra_target) {
    const auto file = dir.path() / (id + ".toml");
    std::ofstream(file) << "id = \"" << id << "\"\nversion = 1\n"
                        << "signals = [\"mc.status.speed_kmh\", \"bms.status.soc_pct\"]\n"
                        << "disk_budget_bytes = 1048576\n"
                        << "start_us = " << now - 3'600'000'000
                        << "\nend_us = " << now + 3'600'000'000
                        << "\n[trigger]\nkind = \"time_window\"\n"
                        << "day_start_s = " << day_second(start)
                        << "\nday_end_s = " << day_second(end)
                        << "\n[sampling]\nkind = \"every\"\nperiod_ms = 500\n"
                        << "[target]\n"
                        << extra_target;
    const auto out = dir.path() / (id + ".signed");
    fleetgw::testing::run_program({FLEETGW_BINARY, "campaign", "sign", file.string(), "--key",
                                   ops.key_file().string(), "--out", out.string()},
                                  dir.path() / "sign.out");
    return fleetgw::testing::read_text_file(out);
  };
  publish_retained(broker.uri(), "fleet/v1/campaigns", sign("window", "all_vehicles = true\n"));
  // For this vehicle, on its own topic, but for a BMS firmware it does not have: never runs.
  publish_retained(broker.uri(), "fleet/v1/" + vehicle + "/campaigns",
                   sign("other-fw", "vehicle_ids = [\"" + vehicle +
                                        "\"]\nfirmware = [{ node = \"bms\", "
                                        "versions = [\"NOPE-9\"] }]\n"));

  ASSERT_TRUE(wait_until([&] { return gw.log_contains("campaign: 'window' accepted"); }, 30s))
      << gw.log();
  ASSERT_TRUE(wait_until([&] { return gw.log_contains("campaign: 'other-fw' accepted"); }, 10s))
      << gw.log();

  // The broker goes down before the window opens on the bike's clock; the window runs and
  // closes offline.
  broker.stop();
  const auto stopped = status_of(dir, config);
  ASSERT_LT(bus_now_us(stopped), start)
      << "too slow a start: the window opened with the broker up\n"
      << stopped.dump();
  const auto before = campaign_status(stopped, "window");
  ASSERT_TRUE(before.is_object()) << stopped.dump();
  ASSERT_EQ(before.value("samples", 1u), 0u) << stopped.dump();
  // Its records are cut 30 s of bus time after their first sample: wait for them, and for the
  // bike's clock to be past the window (a slipping bus takes longer than the wall clock).
  nlohmann::json offline;
  ASSERT_TRUE(wait_until(
      [&] {
        const auto status = status_of(dir, config);
        offline = campaign_status(status, "window");
        return bus_now_us(status) > end && offline.is_object() && offline.value("records", 0u) > 0;
      },
      150s))
      << offline.dump() << gw.log();
  const std::uint64_t kept = offline.value("samples", 0u);
  EXPECT_GE(kept, 2u) << offline.dump();
  EXPECT_LE(kept, 2u * 21u) << offline.dump();  // 2 signals, at most 2 a second, 10 s
  EXPECT_EQ(offline.value("dropped", 1u), 0u);
  const auto other = campaign_status(status_of(dir, config), "other-fw");
  EXPECT_NE(other.value("state", ""), "running") << other.dump();
  EXPECT_EQ(other.value("samples", 1u), 0u) << other.dump();

  // Back online: every record arrives, once.
  broker.start();
  CampaignWatcher backend(broker.uri(), vehicle);
  std::size_t received = 0;
  ASSERT_TRUE(wait_until(
      [&] {
        received = 0;
        for (const auto& [key, r] : backend.records()) received += r.samples_size();
        return received >= kept;
      },
      60s))
      << received << " of " << kept << " samples\n"
      << gw.log() << broker.log();
  EXPECT_EQ(received, kept);
  EXPECT_EQ(backend.duplicates(), 0);
  for (const auto& [key, r] : backend.records()) {
    EXPECT_EQ(r.campaign_id(), "window");
    for (const auto& s : r.samples()) {
      const std::int64_t t = r.base_us() + static_cast<std::int64_t>(s.offset_us());
      EXPECT_GE(t, start) << key;
      EXPECT_LT(t, end) << key;
    }
  }
}

}  // namespace
