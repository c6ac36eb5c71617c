// Store::peek_outbox with skipped kinds (issue 24): the uplink leaves the kinds the broker refuses
// in the outbox until their retry, and the records of other kinds behind them must come out in
// their usual (priority, sequence) order, however many of the skipped kind wait in front.
#include <gtest/gtest.h>

#include <vector>

#include "storage/store.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using namespace testing;

TEST(OutboxSkipKinds, SkippedKindsStayOutAndTheOthersKeepTheirOrder) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("o.db")});
  for (std::int64_t t = 1; t <= 3; ++t) {
    Batch b;
    b.now_us = t;
    // Command results share the top priority with alarms: 50 of them in front of each batch.
    for (int i = 0; i < 50; ++i) {
      b.command_results.push_back(
          {command_result("c-" + std::to_string(t) + "-" + std::to_string(i), t),
           payload_of("cmd")});
    }
    b.faults.push_back({fault_at(t, 7), payload_of("fault")});
    b.telemetry.push_back({telemetry_at(t), payload_of("tel")});
    store.write(b);
  }
  const OutboxKind skip[] = {OutboxKind::kCommandResult};
  const auto entries = store.peek_outbox(4, 1 << 20, skip);
  ASSERT_EQ(entries.size(), 4u) << "the skipped kind's 150 records do not use up the limit";
  const std::vector<OutboxKind> kinds = {OutboxKind::kFault, OutboxKind::kFault, OutboxKind::kFault,
                                         OutboxKind::kTelemetry};
  for (std::size_t i = 0; i < entries.size(); ++i) {
    EXPECT_EQ(entries[i].kind, kinds[i]) << "entry " << i;
    if (i > 0) {
      const auto& a = entries[i - 1];
      const auto& b = entries[i];
      EXPECT_TRUE(a.priority < b.priority || (a.priority == b.priority && a.seq < b.seq)) << i;
    }
  }
  store.release_all();
  const OutboxKind two[] = {OutboxKind::kCommandResult, OutboxKind::kFault};
  const auto rest = store.peek_outbox(100, 1 << 20, two);
  ASSERT_EQ(rest.size(), 3u);
  for (const auto& e : rest) EXPECT_EQ(e.kind, OutboxKind::kTelemetry);
  store.release_all();
  EXPECT_EQ(store.peek_outbox(1000, 1 << 20, {}).size(), 156u) << "nothing skipped: all of it";
}

}  // namespace
}  // namespace fleetgw::storage
