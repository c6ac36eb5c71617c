// Status and Result<T> (env/status.h): what the hot path's callers rely on -- an ok Status is
// the default, an error keeps its code and message, a Result is a value or an error and never
// an ok Status without a value.
#include "env/status.h"

#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <string>

namespace fleetgw {
namespace {

TEST(Status, DefaultIsOkAndAnErrorKeepsItsCodeAndMessage) {
  const Status ok;
  EXPECT_TRUE(ok.ok());
  EXPECT_EQ(ok.code, StatusCode::kOk);
  EXPECT_TRUE(ok.message.empty());

  const Status full = Status::error(StatusCode::kFull, "storage: disk full (SQLITE_FULL)");
  EXPECT_FALSE(full.ok());
  EXPECT_EQ(full.code, StatusCode::kFull);
  EXPECT_EQ(full.message, "storage: disk full (SQLITE_FULL)");
  EXPECT_EQ(full, Status::error(StatusCode::kFull, "storage: disk full (SQLITE_FULL)"));
  EXPECT_NE(full, Status::error(StatusCode::kIo, "storage: disk full (SQLITE_FULL)"));
  EXPECT_NE(full, Status::error(StatusCode::kFull, "another message"));
}

TEST(Status, EveryCodeHasItsOwnName) {
  // The names are what health lines and logs print: one per code, none empty.
  std::set<std::string_view> names;
  for (const auto c : {StatusCode::kOk, StatusCode::kFull, StatusCode::kIo, StatusCode::kInvalid,
                       StatusCode::kUnavailable, StatusCode::kRefused, StatusCode::kOther}) {
    EXPECT_FALSE(to_string(c).empty());
    names.insert(to_string(c));
  }
  EXPECT_EQ(names.size(), 7u);
  EXPECT_EQ(to_string(StatusCode::kOk), "ok");
  EXPECT_EQ(to_string(StatusCode::kFull), "full");
  EXPECT_EQ(to_string(StatusCode::kIo), "io");
  EXPECT_EQ(to_string(StatusCode::kInvalid), "invalid");
}

TEST(Result, HoldsAValueOrAnError) {
  Result<int> seven = 7;
  ASSERT_TRUE(seven.ok());
  EXPECT_EQ(*seven, 7);
  EXPECT_EQ(seven.value(), 7);
  EXPECT_TRUE(seven.status().ok());

  const Result<int> refused = Status::error(StatusCode::kInvalid, "Batch.rides[1].ride_id: empty");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code, StatusCode::kInvalid);
  EXPECT_EQ(refused.status().message, "Batch.rides[1].ride_id: empty");
  EXPECT_EQ(refused.value_or(-1), -1);
  EXPECT_EQ(seven.value_or(-1), 7);
}

TEST(Result, AnOkStatusWithoutAValueBecomesAnErrorNotASilentSuccess) {
  const Result<int> r = Status{};
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.status().code, StatusCode::kOther);
  EXPECT_FALSE(r.status().message.empty());
}

TEST(Result, MembersAndMoveOnlyValues) {
  struct Written {
    std::uint64_t first_seq = 0;
    std::uint64_t end_seq = 0;
  };
  Result<Written> w = Written{3, 5};
  ASSERT_TRUE(w.ok());
  EXPECT_EQ(w->end_seq - w->first_seq, 2u);
  w->end_seq = 9;
  EXPECT_EQ(w.value().end_seq, 9u);

  Result<std::unique_ptr<int>> p = std::make_unique<int>(42);
  ASSERT_TRUE(p.ok());
  const std::unique_ptr<int> taken = std::move(p).value();
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(*taken, 42);

  // Copies keep the error.
  const Result<std::string> e = Status::error(StatusCode::kUnavailable, "mqtt: not connected");
  const Result<std::string> copy = e;
  EXPECT_EQ(copy.status(), e.status());
}

}  // namespace
}  // namespace fleetgw
