// The attention rules and the human summary.
#include <gtest/gtest.h>

#include "gateway/status/status_report.h"
#include "status_doc.h"

namespace fleetgw::status {
namespace {

using nlohmann::json;
using test::healthy_status;

std::vector<std::string> rules_of(const json& doc, const AttentionRules& r = {}) {
  std::vector<std::string> out;
  for (const auto& f : evaluate(doc, r)) out.push_back(f.rule);
  return out;
}

TEST(Attention, HealthyDocumentNeedsNone) {
  EXPECT_TRUE(evaluate(healthy_status()).empty());
}

TEST(Attention, BusNotUp) {
  for (const char* state : {"down", "bus_off", "error_passive", "error_warning"}) {
    json d = healthy_status();
    d["bus"]["state"] = state;
    d["bus"]["detail"] = "ENETDOWN on can0";
    const auto f = evaluate(d);
    ASSERT_EQ(f.size(), 1u) << state;
    EXPECT_EQ(f[0].rule, "bus");
    EXPECT_NE(f[0].detail.find("ENETDOWN"), std::string::npos);
  }
}

TEST(Attention, NodeOfflineOrNeverHeard) {
  json d = healthy_status();
  d["nodes"][1]["online"] = false;
  d["nodes"][1]["last_heard_age_s"] = 45.0;
  d["nodes"][2]["online"] = false;
  d["nodes"][2]["last_heard_age_s"] = nullptr;
  const auto f = evaluate(d);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_NE(f[0].detail.find("bms offline (last heard 45.0 s ago)"), std::string::npos);
  EXPECT_NE(f[1].detail.find("lock1 offline (never heard)"), std::string::npos);
}

TEST(Attention, OnlyCriticalFaults) {
  json d = healthy_status();
  d["faults"].push_back(
      {{"node", "bms"}, {"code", 3}, {"name", "cell_overvoltage"}, {"severity", "critical"}});
  EXPECT_EQ(rules_of(d), std::vector<std::string>{"fault"});
}

TEST(Attention, BrokerDisconnectedUnlessDisabled) {
  json d = healthy_status();
  d["broker"]["connected"] = false;
  d["broker"]["last_error"] = "connection refused";
  const auto f = evaluate(d);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].rule, "broker");
  EXPECT_NE(f[0].detail.find("connection refused"), std::string::npos);
  d["broker"]["enabled"] = false;
  EXPECT_TRUE(evaluate(d).empty());
}

TEST(Attention, GpsdUnreachableButNotANoFixUnderARoof) {
  json d = healthy_status();
  d["gnss"] = {{"enabled", true}, {"gpsd", "localhost:2947"}, {"connected", true},
               {"fix", false},    {"reason", "no fix"},       {"fixes", 0}};
  EXPECT_TRUE(evaluate(d).empty());
  EXPECT_NE(format_summary(d, {}).find("POSITION UNKNOWN: no fix"), std::string::npos);
  d["gnss"]["connected"] = false;
  d["gnss"]["reason"] = "gpsd unreachable";
  const auto f = evaluate(d);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].rule, "gnss");
  EXPECT_NE(f[0].detail.find("localhost:2947"), std::string::npos);
  d["gnss"] = {{"enabled", true},   {"gpsd", "localhost:2947"},
               {"connected", true}, {"fix", true},
               {"lat", 52.52},      {"lon", 13.405},
               {"hdop", 0.9},       {"satellites", 8}};
  EXPECT_TRUE(evaluate(d).empty());
  EXPECT_NE(format_summary(d, {}).find("fix 52.520000, 13.405000"), std::string::npos);
}

TEST(Attention, DiskAboveTheFractionOfTheBudget) {
  json d = healthy_status();
  d["disk"]["used_bytes"] = 0.90 * 268435456;  // exactly at the limit: fine
  EXPECT_TRUE(evaluate(d).empty());
  d["disk"]["used_bytes"] = 0.91 * 268435456;
  EXPECT_EQ(rules_of(d), std::vector<std::string>{"disk"});
  AttentionRules lenient;
  lenient.disk_fraction = 0.95;
  EXPECT_TRUE(evaluate(d, lenient).empty());
}

TEST(Attention, OutboxOldestRecordTooOld) {
  json d = healthy_status();
  d["outbox"]["oldest_unsent_age_s"] = 6 * 3600.0 + 1;
  EXPECT_EQ(rules_of(d), std::vector<std::string>{"outbox"});
  AttentionRules r;
  r.outbox_max_age = std::chrono::hours(12);
  EXPECT_TRUE(evaluate(d, r).empty());
  d["outbox"]["oldest_unsent_age_s"] = nullptr;  // empty outbox
  EXPECT_TRUE(evaluate(d).empty());
}

TEST(Attention, MissingOrMistypedSectionsAreFindingsNotExceptions) {
  json d = healthy_status();
  d.erase("disk");
  d["nodes"] = "mc";
  const auto r = rules_of(d);
  EXPECT_EQ(r, (std::vector<std::string>{"malformed", "malformed"}));
  for (const json& odd : {json(nullptr), json(42), json::array(), json::object()}) {
    EXPECT_NO_THROW(evaluate(odd));
    EXPECT_NO_THROW(format_summary(odd, {}));
    EXPECT_FALSE(evaluate(odd).empty());
  }
  json weird = healthy_status();
  weird["nodes"][0] = 17;  // not an object: offline, no crash
  weird["bus"]["state"] = 3;
  EXPECT_NO_THROW(format_summary(weird, evaluate(weird)));
  EXPECT_EQ(rules_of(weird), (std::vector<std::string>{"bus", "node"}));
}

TEST(Summary, ShowsEverySection) {
  const json d = healthy_status();
  const std::string s = format_summary(d, evaluate(d));
  for (const char* want :
       {"vehicle bike-0042", "can0 (socketcan): up", "rx 120345", "crc 2", "mc     online",
        "firmware MC_V4.6.2", "firmware unknown", "motor_overtemp_warning (code 7, warning)",
        "seat: locked", "frame: unlocked", "ssl://mqtt.example:8883: connected", "3 records",
        "50.0 MiB of 256.0 MiB (19.5 %)", "\nOK\n"}) {
    EXPECT_NE(s.find(want), std::string::npos) << "missing \"" << want << "\" in\n" << s;
  }
}

TEST(Summary, VehicleLineShowsSpeedSocAndTheOpenRide) {
  json d = healthy_status();
  EXPECT_EQ(format_summary(d, {}).find("\nvehicle "), std::string::npos) << "older service";
  d["vehicle"] = {{"speed_kmh", 21.34},
                  {"soc_pct", 63.0},
                  {"riding", true},
                  {"ride", {{"ride_id", "r1"}, {"distance_km", 2.1}, {"duration_s", 361.0}}}};
  EXPECT_NE(format_summary(d, {}).find("\nvehicle  21.3 km/h  SOC 63 %  riding: 2.10 km in 6.0 "
                                       "min (ride r1)\n"),
            std::string::npos)
      << format_summary(d, {});
  d["vehicle"] = {{"speed_kmh", nullptr}, {"soc_pct", nullptr}, {"ride", nullptr}};
  EXPECT_NE(format_summary(d, {}).find("\nvehicle  ? km/h  SOC ? %  parked\n"), std::string::npos)
      << format_summary(d, {});
  d["vehicle"] = "garbage";
  EXPECT_NO_THROW(format_summary(d, evaluate(d)));
  EXPECT_TRUE(evaluate(d).empty()) << "the vehicle section is information, never attention";
}

TEST(Summary, ListsFindings) {
  json d = healthy_status();
  d["broker"]["connected"] = false;
  const std::string s = format_summary(d, evaluate(d));
  EXPECT_NE(s.find("DISCONNECTED"), std::string::npos);
  EXPECT_NE(s.find("ATTENTION: broker ssl://mqtt.example:8883 not connected"), std::string::npos);
  EXPECT_EQ(s.find("\nOK\n"), std::string::npos);
}

}  // namespace
}  // namespace fleetgw::status
