// Issue 24, finding 4, as the finding was made: the shipped `fleetgw run` (child process) on the
// simulated parked bike, a real mosquitto, and a backend publishing signed MC commands back to
// back. Every command must get exactly one definite result (succeeded, or rejected busy /
// mc_busy with its id); a flood of zeroed-signature junk must never silence the genuine command
// behind it, in every repetition; `fleetgw status` must count every dropped input by class.
// No timing is asserted: how many are busy depends on the machine, that each is answered not.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "tests/command/burst_client.h"
#include "tests/runtime/service_process.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/process.h"
#include "tests/support/source_dir.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace fleetgw::command::testing {
namespace {

using namespace std::chrono_literals;

using ::fleetgw::testing::read_text_file;
// FLEETGW_BURST_TEST_BIN runs these tests against another build of the binary (to show they
// fail on one without the fix); the default is the one built with the tests.
std::string fleetgw_binary() {
  const char* other = std::getenv("FLEETGW_BURST_TEST_BIN");
  return other != nullptr && *other != '\0' ? other : FLEETGW_BIN;
}

struct BurstE2e {
  static constexpr const char* kBike = "rt-burst";
  BurstE2e() {
    broker.start();
    fleetgw::testing::service_config(
        kBike, dir.path(), fleetgw::testing::source_dir() / "config" / "scenarios" / "parked.toml",
        1, broker.uri(), "ops", key.public_key().base64())
        .write(dir.path() / "fleetgw.toml");
    service.emplace(fleetgw_binary(), dir.path() / "fleetgw.toml", dir.path() / "service.log");
    ready = fleetgw::testing::wait_until([&] { return service->log_contains("uplink: connected"); },
                                         30s);
    if (ready) backend.emplace(broker.uri(), kBike);
  }

  SentCommand headlight(const std::string& id, bool on) {
    const Micros now =
        std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
    return sign_for_sending(
        *make_mc_command(kBike, "headlight", on ? "on" : "off", now, now + 120s, id), key, "ops");
  }
  // Sends headlight commands one at a time until the gateway has heard the MC (an early one is
  // refused mc_offline / mc_state_unknown); returns how many it sent.
  int until_mc_known() {
    int sent = 0;
    fleetgw::testing::wait_until(
        [&] {
          const std::string id = "warm-" + std::to_string(sent++);
          std::map<std::string, SentCommand> one{{id, headlight(id, false)}};
          backend->publish({one[id].payload});
          if (!backend->wait_for_answers(one, 10s)) return false;
          const std::string code = reason_code_of(backend->answers(one)[id][0]);
          return code != "mc_offline" && code != "mc_state_unknown";
        },
        30s, 200ms);
    return sent;
  }
  // `fleetgw status --format <format>` of the running service.
  std::string status_text(const std::string& format) {
    const auto out = dir.path() / ("status-" + std::to_string(++runs) + ".out");
    fleetgw::testing::run_for_exit_code(
        {FLEETGW_BIN, "status", "--config", (dir.path() / "fleetgw.toml").string(), "--format",
         format},
        out, dir.path() / "status.err");
    return read_text_file(out);
  }
  nlohmann::json commands_status() {
    const auto doc = nlohmann::json::parse(status_text("json"), nullptr, false);
    return doc.is_object() && doc.contains("commands") ? doc["commands"] : nlohmann::json();
  }
  std::string log() const { return read_text_file(dir.path() / "service.log"); }

  fleetgw::testing::TempDir dir{"fleetgw-burst-e2e"};
  fleetgw::testing::MosquittoBroker broker;
  Ed25519PrivateKey key = Ed25519PrivateKey::generate();
  std::optional<fleetgw::testing::ServiceProcess> service;
  std::optional<BurstClient> backend;
  bool ready = false;
  int runs = 0;
};

TEST(CommandMqttBurstE2e, EveryCommandOfAHundredCommandBurstGetsExactlyOneResult) {
  BurstE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  const int warm = rig.until_mc_known();

  constexpr int kBurst = 100;
  std::map<std::string, SentCommand> sent;
  std::vector<std::string> payloads;
  for (int i = 0; i < kBurst; ++i) {
    const std::string id = "burst-" + std::to_string(i);
    sent[id] = rig.headlight(id, i % 2 == 0);
    payloads.push_back(sent[id].payload);
  }
  rig.backend->publish(payloads);
  const bool all = rig.backend->wait_for_answers(sent, 60s);
  const auto answers = rig.backend->answers(sent);
  ASSERT_TRUE(all) << kBurst - answers.size() << " of " << kBurst << " commands got no result\n"
                   << rig.log();

  std::map<std::string, int> by_code;
  for (const auto& [id, list] : answers) {
    ASSERT_EQ(list.size(), 1u) << id;
    const auto& r = list[0];
    const std::string code =
        r.result() == v1::COMMAND_RESULT_CODE_SUCCEEDED ? "succeeded" : reason_code_of(r);
    ++by_code[code];
    EXPECT_TRUE(code == "succeeded" || code == "busy" || code == "mc_busy")
        << id << ": " << r.ShortDebugString();
  }
  EXPECT_GE(by_code["succeeded"], 1);
  std::cout << "100-command burst through fleetgw run: " << by_code["succeeded"] << " succeeded, "
            << by_code["mc_busy"] << " mc_busy, " << by_code["busy"] << " busy, "
            << kBurst - static_cast<int>(answers.size()) << " without a result\n";

  // Status accounts for every authenticated command: taken or answered busy, none dropped.
  nlohmann::json c;
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        c = rig.commands_status();
        return c.is_object() && c["received"].get<int>() + c["busy"].get<int>() == kBurst + warm;
      },
      10s, 100ms))
      << c.dump() << "\n"
      << rig.status_text("json");
  EXPECT_EQ(c["busy"].get<int>(), by_code["busy"]);
  EXPECT_EQ(c["dropped"], 0) << c.dump();
  // Still exactly one each (a late duplicate would show here).
  for (const auto& [id, list] : rig.backend->answers(sent)) EXPECT_EQ(list.size(), 1u) << id;
}

TEST(CommandMqttBurstE2e, AJunkFloodNeverSilencesTheGenuineCommandAndStatusCountsTheDrops) {
  BurstE2e rig;
  ASSERT_TRUE(rig.ready) << rig.log();
  rig.until_mc_known();

  constexpr int kRepetitions = 3;
  constexpr int kJunk = 60;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    std::vector<std::string> payloads;
    for (int i = 0; i < kJunk; ++i) {
      const Micros now =
          std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
      payloads.push_back(
          junk_command(*make_mc_command(BurstE2e::kBike, "headlight", "on", now, now + 60s,
                                        "junk-" + std::to_string(rep) + "-" + std::to_string(i)),
                       "ops"));
    }
    const bool on = rep % 2 == 0;
    const std::string id = "genuine-" + std::to_string(rep);
    std::map<std::string, SentCommand> genuine{{id, rig.headlight(id, on)}};
    payloads.push_back(genuine[id].payload);
    rig.backend->publish(payloads);
    ASSERT_TRUE(rig.backend->wait_for_answers(genuine, 20s))
        << "repetition " << rep << ": the genuine command got no result\n"
        << rig.log();
    const auto r = rig.backend->answers(genuine)[id];
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].result(), v1::COMMAND_RESULT_CODE_SUCCEEDED)
        << "repetition " << rep << ": " << r[0].ShortDebugString();
    EXPECT_EQ(r[0].mc().headlight_on(), on) << r[0].ShortDebugString();
  }

  // An oversized and an undecodable payload, then status counts every drop by class.
  rig.backend->publish({std::string(5000, 'x'),
                        "\x0a\x05"
                        "ab"});
  nlohmann::json c;
  ASSERT_TRUE(fleetgw::testing::wait_until(
      [&] {
        c = rig.commands_status();
        return c.is_object() && c["dropped_by_reason"]["oversized"] == 1 &&
               c["dropped_by_reason"]["undecodable"] == 1;
      },
      10s, 100ms))
      << c.dump() << "\n"
      << rig.status_text("json");
  const auto& by = c["dropped_by_reason"];
  EXPECT_EQ(c["unauthenticated"].get<int>() + by["unauthenticated"].get<int>(),
            kRepetitions * kJunk)
      << c.dump();
  EXPECT_GT(by["unauthenticated"].get<int>(), 0) << c.dump();
  EXPECT_EQ(by["queue_full"], 0);
  EXPECT_EQ(c["dropped"].get<int>(), by["oversized"].get<int>() + by["undecodable"].get<int>() +
                                         by["unauthenticated"].get<int>())
      << c.dump();
  const std::string text = rig.status_text("table");
  EXPECT_NE(text.find("commands"), std::string::npos) << text;
  EXPECT_NE(text.find("unauthenticated"), std::string::npos) << text;
}

}  // namespace
}  // namespace fleetgw::command::testing
