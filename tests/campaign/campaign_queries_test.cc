// docs/backend.md "Campaign samples": each analyst query, exactly as printed there, on rows the
// ingest wrote from campaign records into a real PostgreSQL (a private cluster), with its answer
// checked -- so a schema change that breaks a documented query breaks this test.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "backend/common/pg.h"
#include "backend/ingest/envelope_rows.h"
#include "backend/ingest/ingest_store.h"
#include "fleetgw/v1/envelope.pb.h"
#include "tests/ingest/pg_fixture.h"

namespace fleetgw::ingest {
namespace {

// A window record of hot-pack v3 from `vehicle`: the pack temperature and cell 0 at -1 s, 0 s
// and +1 s around a trigger at `trigger_us`; `temp` at the trigger.
Decoded hot_pack_record(const std::string& vehicle, std::uint64_t seq, std::int64_t trigger_us,
                        double temp) {
  v1::Envelope e;
  e.set_vehicle_id(vehicle);
  e.set_store_id("store-" + vehicle);
  e.set_sequence(seq);
  e.set_created_at_us(trigger_us);
  e.set_gateway_fw_version("0.1.0");
  auto* c = e.mutable_campaign();
  c->set_campaign_id("hot-pack");
  c->set_campaign_version(3);
  c->add_signals("bms.status.temp_c");
  c->add_signals("bms.cells.cells_mv[0]");
  c->set_base_us(trigger_us - 1'000'000);
  c->set_trigger_at_us(trigger_us);
  for (int k = 0; k < 3; ++k) {
    auto* t = c->add_samples();
    t->set_signal(0);
    t->set_offset_us(static_cast<std::uint64_t>(k) * 1'000'000);
    t->set_value_e6(static_cast<std::int64_t>((temp - 1 + k) * 1e6));
    auto* v = c->add_samples();
    v->set_signal(1);
    v->set_offset_us(static_cast<std::uint64_t>(k) * 1'000'000);
    v->set_value_e6(static_cast<std::int64_t>((3300 + k) * 1e6));
    v->set_invalid(vehicle == "bike-2" && k == 2);
  }
  auto r = decode_message("fleet/v1", "fleet/v1/" + vehicle + "/campaign", e.SerializeAsString());
  return std::get<Decoded>(std::move(r));
}

TEST(CampaignQueries, TheAnalystQueriesOfDocsBackendRunOnRealPostgres) {
  if (testing::postgres_bin_dir().empty()) GTEST_SKIP() << "PostgreSQL server binaries missing";
  testing::PostgresCluster cluster;
  IngestStore store(cluster.conninfo(), 100);
  constexpr std::int64_t kT0 = 1'795'910'400'000'000;  // 2026-11-29T00:00:00Z
  store.write(hot_pack_record("bike-1", 1, kT0 + 10'000'000, 46));
  store.write(hot_pack_record("bike-1", 2, kT0 + 70'000'000, 48));
  store.write(hot_pack_record("bike-2", 1, kT0 + 20'000'000, 50));
  // Redelivered: written once.
  EXPECT_EQ(store.write(hot_pack_record("bike-2", 1, kT0 + 20'000'000, 50)).inserted, 0);
  PgConnection pg(cluster.conninfo());
  EXPECT_EQ(pg.exec("SELECT count(*) FROM campaign_samples", "count").int64(0, 0), 18);

  const auto volume = pg.exec(
      "SELECT vehicle_id, signal, count(*) AS samples, count(*) FILTER (WHERE invalid) AS "
      "invalid,\n"
      "       min(sampled_at_us) AS first_us, max(sampled_at_us) AS last_us\n"
      "FROM campaign_samples WHERE campaign_id = 'hot-pack' AND campaign_version = 3\n"
      "GROUP BY 1, 2 ORDER BY 1, 2;",
      "volume");
  ASSERT_EQ(volume.rows(), 4);
  EXPECT_EQ(volume.text(0, 0), "bike-1");
  EXPECT_EQ(volume.text(0, 1), "bms.cells.cells_mv[0]");
  EXPECT_EQ(volume.int64(0, 2), 6);
  EXPECT_EQ(volume.int64(0, 4), kT0 + 9'000'000);
  EXPECT_EQ(volume.int64(0, 5), kT0 + 71'000'000);
  EXPECT_EQ(volume.text(2, 0), "bike-2");
  EXPECT_EQ(volume.int64(2, 3), 1);  // bike-2's invalid cell sample

  const auto window = pg.exec(
      "SELECT vehicle_id, trigger_at_us, signal,\n"
      "       (sampled_at_us - trigger_at_us) / 1000 AS ms_from_trigger, value\n"
      "FROM campaign_samples\n"
      "WHERE campaign_id = 'hot-pack' AND trigger_at_us IS NOT NULL\n"
      "ORDER BY vehicle_id, trigger_at_us, sampled_at_us, signal;",
      "window");
  ASSERT_EQ(window.rows(), 18);
  EXPECT_EQ(window.text(0, 2), "bms.cells.cells_mv[0]");
  EXPECT_EQ(window.int64(0, 3), -1000);
  EXPECT_EQ(window.text(1, 2), "bms.status.temp_c");
  EXPECT_EQ(window.text(1, 4), "45");
  EXPECT_EQ(window.int64(5, 3), 1000);

  const auto events = pg.exec(
      "SELECT vehicle_id, count(DISTINCT trigger_at_us) AS events, max(value) AS max_value\n"
      "FROM campaign_samples\n"
      "WHERE campaign_id = 'hot-pack' AND signal = 'bms.status.temp_c' AND trigger_at_us IS NOT "
      "NULL\n"
      "GROUP BY 1 ORDER BY events DESC;",
      "events");
  ASSERT_EQ(events.rows(), 2);
  EXPECT_EQ(events.text(0, 0), "bike-1");
  EXPECT_EQ(events.int64(0, 1), 2);
  EXPECT_EQ(events.text(0, 2), "49");
  EXPECT_EQ(events.text(1, 2), "51");

  const auto per_minute = pg.exec(
      "SELECT sampled_at_us / 60000000 AS minute, count(DISTINCT vehicle_id) AS vehicles,\n"
      "       min(value), avg(value), max(value)\n"
      "FROM campaign_samples\n"
      "WHERE campaign_id = 'hot-pack' AND signal = 'bms.cells.cells_mv[0]' AND NOT invalid\n"
      "GROUP BY 1 ORDER BY 1;",
      "per minute");
  ASSERT_EQ(per_minute.rows(), 2);
  EXPECT_EQ(per_minute.int64(0, 0), kT0 / 60'000'000);
  EXPECT_EQ(per_minute.int64(0, 1), 2);
  EXPECT_EQ(per_minute.text(0, 4), "3302");
  EXPECT_EQ(per_minute.int64(1, 1), 1);
}

}  // namespace
}  // namespace fleetgw::ingest
