// The sentence and counts of `fleetgw db summary` (gateway/tools/store/db_summary.h) from listing
// rows, without a store: plurals, empty areas, reasons by code, alarm kinds in words, hostile
// strings.
#include <gtest/gtest.h>

#include "gateway/tools/store/db_summary.h"

namespace fleetgw::tools {
namespace {

using nlohmann::json;

json command(const char* result, const char* reason) {
  return {{"command_id", "c"}, {"result", result}, {"reason", reason}};
}

TEST(DbSummary, EmptyStoreSaysSoInEveryArea) {
  const DbSummary s = summarize({}, std::nullopt);
  EXPECT_EQ(summary_sentence(s), "no rides; no faults; no commands; no alarms");
  EXPECT_EQ(summary_json(s)["since"], nullptr);
  EXPECT_EQ(summary_table(s).rows.size(), 4u);
}

TEST(DbSummary, SingularsAndTheDemoStory) {
  SummaryRows rows;
  rows.rides.push_back({{"state", "closed"},
                        {"start_odo_km", 872.3},
                        {"end_odo_km", 880.4},
                        {"distance_km", 8.1},
                        {"distance_integrated_km", 8.0},
                        {"duration_s", 28 * 60.0}});
  rows.faults.push_back({{"node", 1}, {"name", "over_heat_protect"}, {"event", "raised"}});
  rows.faults.push_back({{"node", 1}, {"name", "over_heat_protect"}, {"event", "cleared"}});
  rows.commands.push_back(command("succeeded", ""));
  rows.commands.push_back(command("succeeded", ""));
  rows.commands.push_back(command("rejected", "interlock_moving: will not lock the frame lock"));
  rows.alarms.push_back({{"kind", "unauthorised_movement"}, {"transition", "raised"}});
  rows.alarms.push_back({{"kind", "unauthorised_movement"}, {"transition", "cleared"}});
  const DbSummary s = summarize(rows, 1717228800000000);
  EXPECT_EQ(summary_sentence(s),
            "1 ride, 8.1 km, 28 min; 1 fault raised, 1 cleared; 3 commands: 2 succeeded, 1 "
            "refused (interlock_moving); 1 alarm (theft)");
  const json j = summary_json(s);
  EXPECT_EQ(j["since"], "2024-06-01T08:00:00Z");
  EXPECT_EQ(j["faults"]["raised_by_fault"], (json{{"mc:over_heat_protect", 1}}));
  EXPECT_EQ(j["commands"]["refused_by_reason"], (json{{"interlock_moving", 1}}));
}

TEST(DbSummary, ReasonsByCodeAndOtherResults) {
  SummaryRows rows;
  for (const char* r : {"interlock_moving: a", "interlock_moving: b", "lock_busy: c"}) {
    rows.commands.push_back(command("rejected", r));
  }
  rows.commands.push_back(command("rejected", ""));
  rows.commands.push_back(command("timeout", "no_confirmation: lock silent"));
  rows.commands.push_back({{"command_id", "d"}, {"state", "executing"}, {"result", nullptr}});
  rows.commands.push_back({{"command_id", "e"}});  // neither result nor state
  const DbSummary s = summarize(rows, std::nullopt);
  EXPECT_EQ(s.refused_by_reason,
            (std::map<std::string, std::uint64_t>{
                {"interlock_moving", 2}, {"lock_busy", 1}, {"unspecified", 1}}));
  EXPECT_EQ(s.failed_by_reason, (std::map<std::string, std::uint64_t>{{"no_confirmation", 1}}));
  EXPECT_EQ(summary_sentence(s),
            "no rides; no faults; 7 commands: 4 refused (2 interlock_moving, 1 lock_busy, 1 "
            "unspecified), 1 timed out, 1 executing, 1 unknown; no alarms");
}

TEST(DbSummary, OpenRidesIntegratedDistanceAlarmWordsAndUnknownKinds) {
  SummaryRows rows;
  rows.rides.push_back({{"state", "open"}, {"distance_integrated_km", 1.26}, {"duration_s", 100}});
  rows.rides.push_back({{"state", "closed"}, {"partial", 1}, {"distance_km", "bad"}});
  for (const char* kind : {"lock_forced", "low_battery", "low_battery", "new_kind"}) {
    rows.alarms.push_back({{"kind", kind}, {"transition", "raised"}});
  }
  rows.faults.push_back({{"node", 2}, {"name", "x"}, {"event", "unknown"}});
  const DbSummary s = summarize(rows, std::nullopt);
  EXPECT_EQ(s.rides_partial, 1u);
  EXPECT_EQ(summary_sentence(s),
            "2 rides, 1.3 km, 2 min (1 open); 0 faults raised, 0 cleared, 1 unknown; no "
            "commands; 4 alarms (1 forced lock, 2 low battery, 1 new_kind)");
}

TEST(DbSummary, HostileStringsNeverBreakTheSentence) {
  SummaryRows rows;
  rows.commands.push_back(command("rejected", "evil\n\x1b[2Jreason: detail"));
  rows.alarms.push_back({{"kind", "kind\r\nforged line"}, {"transition", "raised"}});
  rows.commands.push_back(command("weird\tresult", ""));
  const std::string s = summary_sentence(summarize(rows, std::nullopt));
  for (const char c : s) EXPECT_GE(static_cast<unsigned char>(c), 0x20) << s;
  EXPECT_NE(s.find("1 refused (evil\\n\\x1b[2Jreason)"), std::string::npos) << s;
  EXPECT_NE(s.find("1 weird\\tresult"), std::string::npos) << s;
  EXPECT_NE(s.find("1 alarm (kind\\r\\nforged line)"), std::string::npos) << s;
}

TEST(DbSummary, NonObjectRowsCountAsAbsentValues) {
  SummaryRows rows;
  rows.rides.push_back(json(17));
  rows.faults.push_back(json::array());
  EXPECT_NO_THROW(summary_sentence(summarize(rows, std::nullopt)));
}

}  // namespace
}  // namespace fleetgw::tools
