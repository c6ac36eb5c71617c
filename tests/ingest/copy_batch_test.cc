// The batch write built from COPY text (issue 25) against a real PostgreSQL: the paths a
// redelivery and the latest-value tables take (text[] arrays made from the COPY text) keep every
// byte and NULL, text the server refuses (invalid UTF-8 from a non-proto3 sender) is refused
// for its message alone, and the worst shape of a batch's ranges (one vehicle, thousands of
// one-record ranges, then the records between them) merges exactly.
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "backend/ingest/ingest_store.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"

namespace {

using fleetgw::PgConnection;
using fleetgw::ingest::Decoded;
using fleetgw::ingest::IngestStore;
using fleetgw::testing::decoded;
using fleetgw::testing::PgDatabaseTest;
namespace v1 = fleetgw::v1;

const std::string kHostileText = "tab\there \"quoted\" back\\slash \\N new\nline\r {a,b}";

class CopyBatchTest : public PgDatabaseTest {
 protected:
  static Decoded fault(std::uint64_t seq, const std::string& name, bool with_code) {
    v1::Envelope e;
    e.set_vehicle_id("b1");
    e.set_store_id("s1");
    e.set_sequence(seq);
    e.mutable_fault()->set_node("mc");
    e.mutable_fault()->set_name(name);
    if (with_code) e.mutable_fault()->set_code(7);
    return decoded(e, "fault");
  }
  static std::vector<const Decoded*> pointers(const std::vector<Decoded>& v) {
    std::vector<const Decoded*> out;
    for (const Decoded& d : v) out.push_back(&d);
    return out;
  }
};

// A batch holding a redelivered record makes its table's COPY fail on the key; the whole table
// then goes through the text[] statement built from the COPY text: the new record's text and
// NULL arrive exactly as with the COPY.
TEST_F(CopyBatchTest, RedeliveryPathKeepsEveryByteAndNull) {
  IngestStore s(conninfo());
  s.write(fault(1, "plain", true));
  const std::vector<Decoded> batch = {fault(1, "plain", true), fault(2, kHostileText, false)};
  const auto r = s.write_batch(pointers(batch));
  EXPECT_EQ(r.stats.duplicates, 1);
  EXPECT_EQ(r.stats.inserted, 1);
  EXPECT_EQ(text("SELECT name FROM fault_events WHERE sequence = 2"), kHostileText);
  EXPECT_EQ(text("SELECT code FROM fault_events WHERE sequence = 2"), "<null>");
  EXPECT_EQ(text("SELECT code FROM fault_events WHERE sequence = 1"), "7");
  EXPECT_TRUE(s.gaps().empty());
}

// The latest-value upsert (one per vehicle and batch) from COPY text: separators, quotes and
// backslashes in a state's text, NULL for what it does not carry.
TEST_F(CopyBatchTest, StateUpsertFromCopyTextKeepsTextAndNull) {
  IngestStore s(conninfo());
  const auto state = [](std::int64_t at, const std::string& assist_name) {
    v1::Envelope e;
    e.set_vehicle_id("b\t2");
    e.mutable_state()->set_updated_at_us(at);
    e.mutable_state()->set_assist_name(assist_name);
    return decoded(e, "state");
  };
  const std::vector<Decoded> batch = {state(1'000, "old"), state(3'000, kHostileText),
                                      state(2'000, "out of order")};
  const auto r = s.write_batch(pointers(batch));
  EXPECT_EQ(r.stats.stale_states, 1);  // 2,000 after 3,000 in the same batch
  EXPECT_EQ(text("SELECT assist_name FROM vehicle_state WHERE vehicle_id = E'b\\t2'"),
            kHostileText);
  EXPECT_EQ(text("SELECT updated_at_us FROM vehicle_state"), "3000");
  EXPECT_EQ(text("SELECT soc_pct FROM vehicle_state"), "<null>");
}

// Text that is not UTF-8 (a sender that is not proto3's: protobuf itself refuses it in a
// string field) is refused by the server: that message alone is rejected with the server's
// reason, the rest of its batch commits.
TEST_F(CopyBatchTest, InvalidUtf8IsRefusedForItsMessageAlone) {
  IngestStore s(conninfo());
  std::vector<Decoded> batch = {fault(1, "ok", true), fault(2, "XXXX", true), fault(3, "ok", true)};
  std::string& copy = batch[1].rows.at(0).copy;
  copy.replace(copy.find("XXXX"), 4, std::string("\xff\xfe\0z", 4));
  const auto r = s.write_batch(pointers(batch));
  ASSERT_EQ(r.refused.size(), 3u);
  EXPECT_FALSE(r.refused[0].has_value());
  ASSERT_TRUE(r.refused[1].has_value());
  EXPECT_EQ(r.refused[1]->code, "database_refused");
  EXPECT_FALSE(r.refused[2].has_value());
  EXPECT_EQ(text("SELECT string_agg(sequence::text, ',' ORDER BY sequence) FROM fault_events"),
            "1,3");
}

// The worst shape of a batch for the range bookkeeping: one vehicle, 3,000 one-record ranges
// (every other sequence), then a batch of the 3,000 between them: one range, no gap.
TEST_F(CopyBatchTest, OneVehicleWithThousandsOfTinyRangesMergesExactly) {
  IngestStore s(conninfo());
  std::vector<Decoded> odd, even;
  for (std::uint64_t q = 1; q <= 6'000; ++q) (q % 2 == 1 ? odd : even).push_back(fault(q, "f", true));
  s.write_batch(pointers(odd));
  EXPECT_EQ(text("SELECT count(*) FROM sequence_ranges"), "3000");
  EXPECT_EQ(s.gaps().size(), 2'999u);
  // Half of them again (a redelivery) with the rest: still exact.
  std::vector<Decoded> rest = std::move(even);
  for (std::uint64_t q = 1; q <= 3'000; q += 2) rest.push_back(fault(q, "f", true));
  const auto r = s.write_batch(pointers(rest));
  EXPECT_EQ(r.stats.duplicates, 1'500);
  EXPECT_EQ(text("SELECT first_seq || '-' || last_seq FROM sequence_ranges"), "1-6000");
  EXPECT_TRUE(s.gaps().empty());
  EXPECT_EQ(text("SELECT count(*) FROM fault_events"), "6000");
}

// The shapes one (vehicle, store) range per batch takes in a stream: one growing the stored
// range (the common case), a redelivered range inside a stored one (changes nothing), one
// reaching the next stored range (joins both): the accounted ranges stay exact.
TEST_F(CopyBatchTest, SingleRangesGrowInPlaceWithoutSwallowingTheNext) {
  IngestStore s(conninfo());
  const auto write = [&](std::uint64_t first, std::uint64_t last) {
    std::vector<Decoded> v;
    for (std::uint64_t q = first; q <= last; ++q) v.push_back(fault(q, "f", true));
    return s.write_batch(pointers(v)).stats;
  };
  const auto ranges = [&] {
    return text(
        "SELECT string_agg(first_seq || '-' || last_seq, ' ' ORDER BY first_seq) FROM "
        "sequence_ranges");
  };
  write(1, 10);
  write(20, 30);
  ASSERT_EQ(ranges(), "1-10 20-30");
  write(11, 15);  // grows 1-10 in place
  EXPECT_EQ(ranges(), "1-15 20-30");
  EXPECT_EQ(write(5, 7).duplicates, 3);  // covered: nothing changes
  EXPECT_EQ(ranges(), "1-15 20-30");
  write(16, 19);  // reaches 20-30: one range
  EXPECT_EQ(ranges(), "1-30");
  write(31, 31);
  EXPECT_EQ(ranges(), "1-31");
  EXPECT_TRUE(s.gaps().empty());
}

// A vehicle's state, replaced batch after batch, stays on its page (a HOT update: no index entry
// and no page of its own per replacement, migration 10), even when the page holds as many other
// vehicles' states as fit: the table keeps room on each page for the next version.
TEST_F(CopyBatchTest, ReplacedStatesStayOnTheirPage) {
  IngestStore s(conninfo());
  const auto state = [](int vehicle, std::int64_t at) {
    v1::Envelope e;
    e.set_vehicle_id("bike-" + std::to_string(vehicle));
    e.mutable_state()->set_updated_at_us(at);
    e.mutable_state()->set_assist_name(std::string(200, 'a'));  // a state's usual size
    return decoded(e, "state");
  };
  std::vector<Decoded> fleet;
  for (int v = 0; v < 100; ++v) fleet.push_back(state(v, 1'000));
  s.write_batch(pointers(fleet));
  const auto page_of = [&](int vehicle) {
    return text("SELECT (ctid::text::point)[0] FROM vehicle_state WHERE vehicle_id = 'bike-" +
                std::to_string(vehicle) + "'");
  };
  ASSERT_EQ(page_of(0), "0");
  for (std::int64_t at = 2'000; at <= 4'000; at += 1'000) {
    const std::vector<Decoded> next = {state(0, at)};
    s.write_batch(pointers(next));
    EXPECT_EQ(page_of(0), "0") << "the state of " << at << " moved to another page";
  }
  EXPECT_EQ(text("SELECT updated_at_us FROM vehicle_state WHERE vehicle_id = 'bike-0'"), "4000");
}

// committed_at_us is the batch's one stamp in every table it writes (the column's default reads
// the setting the batch makes: migration 9), and a writer that sets nothing (an analyst's
// INSERT) still gets the database's clock, never NULL.
TEST_F(CopyBatchTest, OneStampPerBatchAcrossTablesAndTheClockForOtherWriters) {
  IngestStore s(conninfo());
  v1::Envelope t;
  t.set_vehicle_id("b1");
  t.set_store_id("s1");
  for (std::uint64_t q = 1; q <= 3; ++q) t.mutable_telemetry()->add_samples()->set_sequence(q);
  const std::vector<Decoded> batch = {decoded(t, "telemetry"), fault(4, "f", true)};
  s.write_batch(pointers(batch));
  EXPECT_EQ(text("SELECT count(DISTINCT committed_at_us) FROM (SELECT committed_at_us FROM "
                 "telemetry_samples UNION ALL SELECT committed_at_us FROM fault_events) u"),
            "1");
  PgConnection c(conninfo());
  c.exec("INSERT INTO fault_events (vehicle_id, store_id, sequence, created_at_us, "
         "gateway_fw_version, node, bit, name, severity, kind) VALUES ('b9', 's9', 1, 0, '', "
         "'mc', 0, 'n', 's', 'k')",
         "analyst insert");
  const auto r = c.exec(
      "SELECT committed_at_us BETWEEN fleet_now_us() - 60000000 AND fleet_now_us() FROM "
      "fault_events WHERE vehicle_id = 'b9'",
      "stamp");
  EXPECT_EQ(r.text(0, 0), "t");
}

}  // namespace
