// Record vocabulary: kind names round-trip (they are stored as text in the outbox), and the
// eviction report's JSON carries every counter.
#include "storage/records.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <set>

namespace fleetgw::storage {
namespace {

TEST(Records, OutboxKindNamesRoundTripAndAreDistinct) {
  std::set<std::string_view> names;
  for (int k = 0; k <= static_cast<int>(OutboxKind::kEvictionReport); ++k) {
    auto kind = static_cast<OutboxKind>(k);
    auto name = to_string(kind);
    EXPECT_NE(name, "invalid");
    EXPECT_EQ(outbox_kind_from_string(name), kind);
    names.insert(name);
  }
  EXPECT_EQ(names.size(), 9u);
  EXPECT_EQ(to_string(OutboxKind::kCommandResult), "command_result");
  EXPECT_EQ(outbox_kind_from_string("Telemetry"), std::nullopt);
  EXPECT_EQ(to_string(static_cast<OutboxKind>(200)), "invalid");
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
