// Record vocabulary: kind names round-trip (they are stored as text in the outbox), and the
// eviction report's JSON carries every counter.
#include "storage/records.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <set>

namespace fleetgw::storage {
namespace {

// Every kind of the record-kind table round-trips through the outbox's TEXT column, under the
// names existing stores hold (they must still read).
TEST(Records, OutboxKindNamesRoundTripAndAreDistinct) {
  std::set<std::string_view> names;
  for (const auto& spec : records::kRecordKinds) {
    const auto name = to_string(spec.kind);
    EXPECT_EQ(name, spec.stored_name);
    EXPECT_EQ(outbox_kind_from_string(name), spec.kind) << name;
    names.insert(name);
  }
  EXPECT_EQ(names.size(), records::kRecordKinds.size());
  const std::set<std::string_view> stored_by_earlier_versions = {
      "telemetry", "ride", "fault", "pack", "lock", "info", "status", "command_result",
      "eviction_report", "alarm", "zone", "campaign"};
  EXPECT_EQ(names, stored_by_earlier_versions);
  EXPECT_EQ(outbox_kind_from_string("Telemetry"), std::nullopt);
  EXPECT_EQ(to_string(static_cast<OutboxKind>(200)), "invalid");
}

TEST(Records, AnUnknownStoredKindIsRefusedByName) {
  EXPECT_EQ(outbox_kind_from_string("cmd_result"), std::nullopt);
  // The name comes from a file: printed, but never as a line break into the log.
  const std::string why = records::unknown_kind_message("teleport\n");
  EXPECT_NE(why.find("unknown record kind 'teleport?'"), std::string::npos) << why;
  EXPECT_NE(why.find("command_result"), std::string::npos) << why;
}

TEST(Records, PriorityOrderMatchesIssue) {
  EXPECT_LT(OutboxPriority::kCommandResult, OutboxPriority::kFault);
  EXPECT_LT(OutboxPriority::kFault, OutboxPriority::kRide);
  EXPECT_LT(OutboxPriority::kRide, OutboxPriority::kLock);
  EXPECT_LT(OutboxPriority::kLock, OutboxPriority::kPack);
  EXPECT_LT(OutboxPriority::kPack, OutboxPriority::kTelemetry);
  EXPECT_EQ(static_cast<int>(OutboxPriority::kTelemetry), kLowestPriority);
}

TEST(Records, EvictionReportJson) {
  EvictionPass r;
  r.at_us = 5;
  r.budget_bytes = 100;
  r.bytes_before = 120;
  r.bytes_after = 80;
  r.telemetry_rows = 7;
  r.pack_snapshot_rows = 2;
  r.outbox_rows = 6;
  auto j = nlohmann::json::parse(r.to_json());
  EXPECT_EQ(j["at_us"], 5);
  EXPECT_EQ(j["budget_bytes"], 100);
  EXPECT_EQ(j["bytes_before"], 120);
  EXPECT_EQ(j["bytes_after"], 80);
  EXPECT_EQ(j["evicted"]["telemetry"], 7);
  EXPECT_EQ(j["evicted"]["pack_snapshots"], 2);
  EXPECT_EQ(j["evicted"]["outbox"], 6);
  EXPECT_EQ(j["budget_exhausted"], false);
  EXPECT_TRUE(j["oldest_telemetry_kept_us"].is_null());
  r.oldest_telemetry_kept_us = 42;
  EXPECT_EQ(nlohmann::json::parse(r.to_json())["oldest_telemetry_kept_us"], 42);
}

}  // namespace
}  // namespace fleetgw::storage
