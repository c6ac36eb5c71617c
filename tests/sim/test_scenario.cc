// Scenario files: every bundled scenario loads, and bad input is rejected with file, line and
// key.

#include <gtest/gtest.h>

#include <filesystem>

#include "gateway/sim/scenario.h"
#include "sim_test_util.h"

namespace fleetgw::sim {
namespace {

using testing::bundled;

TEST(Scenario, BundledScenariosLoad) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(bundled_scenario_dir())) {
    if (entry.path().extension() != ".toml") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(load_scenario(entry.path()));
    ++count;
  }
  EXPECT_GE(count, 6);
}

TEST(Scenario, RideScenarioContents) {
  const Scenario s = bundled("ride");
  EXPECT_EQ(s.name, "ride");
  EXPECT_EQ(s.seed, 20240601u);
  EXPECT_DOUBLE_EQ(s.soc_pct, 82);
  EXPECT_EQ(s.start, Micros(int64_t{1'717'228'800} * 1'000'000));  // 2024-06-01T08:00:00Z
  ASSERT_EQ(s.ride.size(), 11u);
  EXPECT_EQ(s.ride[4].assist, uint8_t{0x03});
  EXPECT_DOUBLE_EQ(s.ride[4].grade_pct, 5);
  EXPECT_GT(s.ride_duration(), Micros(25 * 60 * 1'000'000LL));
  EXPECT_LT(s.ride_duration(), Micros(31 * 60 * 1'000'000LL));
}

TEST(Scenario, FaultsScenarioEvents) {
  const Scenario s = bundled("faults");
  ASSERT_FALSE(s.events.empty());
  // Sorted by time, names resolved to bits.
  for (std::size_t i = 1; i < s.events.size(); ++i) EXPECT_LE(s.events[i - 1].at, s.events[i].at);
  bool saw_overheat = false;
  for (const ScenarioEvent& e : s.events) {
    if (e.action == Action::kFault && e.node == motinova::Node::kMc) {
      EXPECT_EQ(e.bits, 0x0010u);
      saw_overheat = true;
    }
  }
  EXPECT_TRUE(saw_overheat);
}

// Expects parse_scenario to fail with this line and key, and the message to contain `what`.
void expect_error(const std::string& text, std::size_t line, const std::string& key,
                  const std::string& what) {
  try {
    parse_scenario(text, "bad.toml");
    FAIL() << "accepted: " << text;
  } catch (const ScenarioError& e) {
    EXPECT_EQ(e.file(), "bad.toml");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.key(), key) << e.what();
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("bad.toml:" + std::to_string(line) + ": ", 0), 0u)
        << e.what();
  }
}

TEST(Scenario, UnknownKeyNamesFileLineKey) {
  expect_error("[bike]\nseed = 1\nsoc_pc = 50\n", 3, "bike.soc_pc", "unknown key");
  expect_error(
      "[[ride]]\nduration_s = 5\nspeed_kmh = 10\n[[ride]]\nduration_s = 5\n"
      "speed_kmh = 10\nsped = 3\n",
      7, "ride[1].sped", "unknown key");
  expect_error("colour = \"red\"\n", 1, "colour", "unknown key");
  expect_error("[bike.mc]\nmodel = \"X\"\nfirmware = \"V1\"\n", 3, "bike.mc.firmware",
               "unknown key");
}

TEST(Scenario, KeyNotUsedByActionIsRejected) {
  expect_error("[[event]]\nat_s = 1\naction = \"power_off\"\nnode = \"mc\"\n", 4, "event[0].node",
               "not used by action 'power_off'");
}

TEST(Scenario, RepeatedEventExpandsIntoCopies) {
  const auto s = parse_scenario(
      "[[event]]\nat_s = 1\naction = \"lock\"\nnode = \"lock1\"\nrepeat_every_s = 2\n"
      "repeat_count = 3\n[[event]]\nat_s = 2\naction = \"unlock\"\nnode = \"lock1\"\n",
      "rep.toml");
  ASSERT_EQ(s.events.size(), 4u);
  EXPECT_EQ(s.events[0].at, Micros(1'000'000));
  EXPECT_EQ(s.events[1].action, Action::kUnlock);
  EXPECT_EQ(s.events[2].at, Micros(3'000'000));
  EXPECT_EQ(s.events[3].at, Micros(5'000'000));
  EXPECT_EQ(s.events[3].action, Action::kLock);
  expect_error("[[event]]\nat_s = 1\naction = \"power_off\"\nrepeat_every_s = 2\n", 1,
               "event[0].repeat_count", "repeat_every_s and repeat_count go together");
}

TEST(Scenario, WrongTypeIsRejected) {
  expect_error("[bike]\nsoc_pct = \"full\"\n", 2, "bike.soc_pct", "expected a number");
  expect_error("[bike]\nseed = 1.5\n", 2, "bike.seed", "expected an integer");
  expect_error("[bike]\nheadlight = 1\n", 2, "bike.headlight", "expected true or false");
  expect_error("bike = 3\n", 1, "bike", "expected a table");
}

TEST(Scenario, OutOfRangeIsRejected) {
  expect_error("[bike]\nsoc_pct = 120\n", 2, "bike.soc_pct", "0..100");
  expect_error("[[ride]]\nduration_s = 10\nspeed_kmh = 75\n", 3, "ride[0].speed_kmh", "0..60");
  expect_error("[bike]\ncapacity_mah = 70000\n", 2, "bike.capacity_mah", "1000..65535");
  expect_error("[bike]\nassist = 9\n", 2, "bike.assist", "not one of");
  expect_error("[bike.mc]\nmodel = \"ABCDEFGHIJKLMNOPQ\"\n", 2, "bike.mc.model", "longer than 16");
}

TEST(Scenario, EventErrors) {
  expect_error("[[event]]\nat_s = 1\naction = \"explode\"\n", 3, "event[0].action",
               "unknown value \"explode\"");
  expect_error("[[event]]\nat_s = 1\naction = \"fault\"\nnode = \"mc\"\nfault = \"melted\"\n", 5,
               "event[0].fault", "unknown mc fault \"melted\"");
  expect_error("[[event]]\nat_s = 1\naction = \"jam_lock\"\nnode = \"bms\"\n", 4, "event[0].node",
               "lock1..lock5");
  expect_error(
      "[bike]\nlock_kinds = [\"seat\", \"\", \"\", \"\", \"\"]\n[[event]]\nat_s = 1\n"
      "action = \"unlock\"\nnode = \"lock2\"\n",
      6, "event[0].node", "not fitted");
  // Missing required key: reported at the table's line.
  expect_error("[bike]\nseed = 1\n\n[[event]]\naction = \"fault\"\nnode = \"mc\"\nbits = 1\n", 4,
               "event[0].at_s", "missing key");
}

TEST(Scenario, TomlSyntaxErrorHasLine) {
  expect_error("[bike]\nseed = 1\nsoc_pct = = 3\n", 3, "", "");
}

TEST(Scenario, MissingFileIsAnError) {
  EXPECT_THROW(load_scenario("/nonexistent/scenario.toml"), ScenarioError);
}

TEST(Scenario, DefaultsWithoutTables) {
  const Scenario s = parse_scenario("", "empty.toml");
  EXPECT_TRUE(s.ride.empty());
  EXPECT_EQ(s.effective_duration(), Micros(60'000'000));
  for (std::size_t i = 0; i < kSimLocks; ++i) EXPECT_TRUE(s.lock_fitted(i));
}

}  // namespace
}  // namespace fleetgw::sim
