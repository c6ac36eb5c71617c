// Campaign records in the store (issue 29) over real SQLite files: under the store's disk
// pressure they are evicted (lowest campaign priority first, oldest first) and every fault and
// alarm survives, the eviction counted and reported like telemetry's; each campaign's records go
// out at an outbox priority of their own; a campaign's use of its disk budget survives a restart.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "campaign_test_util.h"
#include "gateway/campaign/campaign_service.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::campaign {
namespace {

using test::kDay0;
using test::kMs;
using test::kSecond;

// A record of `id` whose base_us is `index` (to tell records apart) padded to about `bytes`.
storage::Bytes budget_record(const std::string& id, std::int64_t index, std::size_t bytes) {
  v1::CampaignSamples rec;
  rec.set_campaign_id(id);
  rec.set_campaign_version(1);
  rec.add_signals("mc.status.motor_temp_c");
  rec.set_base_us(index);
  for (std::size_t i = 0; i * 8 < bytes; ++i) {
    auto* s = rec.add_samples();
    s->set_offset_us(i * 1000);
    s->set_value_e6(static_cast<std::int64_t>(i) * 1'000'003);
  }
  const std::string out = rec.SerializeAsString();
  return storage::Bytes(out.begin(), out.end());
}

storage::FaultEventRow budget_fault(std::int64_t t, int code) {
  storage::FaultEventRow f;
  f.node = 1;
  f.bit = code % 32;
  f.code = code;
  f.name = "motor_overtemp";
  f.severity = "warning";
  f.event = storage::FaultEventKind::kRaised;
  f.first_seen_us = f.last_seen_us = t;
  return f;
}

storage::AlarmRow budget_alarm(std::int64_t t) {
  storage::AlarmRow a;
  a.ts_us = a.first_evidence_us = t;
  a.kind = "tamper";
  return a;
}

storage::Bytes text_bytes(std::string_view s) {
  return storage::Bytes(s.begin(), s.end());
}

TEST(CampaignEviction, UnderDiskPressureCampaignRecordsGoAndEveryFaultAndAlarmStays) {
  testing::TempDir dir;
  const std::string path = (dir.path() / "pressure.db").string();
  constexpr std::uint64_t kBudget = 2 << 20;
  const int urgent_priority = CampaignService::outbox_priority(0);  // 6
  const int bulk_priority = CampaignService::outbox_priority(9);    // 15
  ASSERT_EQ(urgent_priority, 6);
  ASSERT_EQ(bulk_priority, 15);

  storage::Store store(storage::StoreOptions{.path = path, .max_bytes = kBudget});
  std::uint64_t reported = 0, reported_outbox = 0, passes = 0;
  constexpr int kBatches = 120;
  for (int i = 0; i < kBatches; ++i) {
    storage::Batch b;
    const std::int64_t t = (kDay0 + i * kSecond).count();
    b.now_us = t;
    b.faults.push_back({budget_fault(t, i), text_bytes("fault")});
    b.faults.push_back({budget_fault(t + 1, i + 1000), text_bytes("fault")});
    b.alarms.push_back({budget_alarm(t), text_bytes("alarm")});
    b.messages.push_back(
        {storage::OutboxKind::kCampaign, urgent_priority, budget_record("urgent", i, 2'000)});
    for (int k = 0; k < 3; ++k) {
      b.messages.push_back(
          {storage::OutboxKind::kCampaign, bulk_priority, budget_record("bulk", i * 3 + k, 8'000)});
    }
    const auto r = store.write(b);
    ASSERT_TRUE(r.ok()) << r.status().message;
    if (r->eviction) {
      ++passes;
      EXPECT_GT(r->eviction->campaign_records, 0u);
      EXPECT_FALSE(r->eviction->budget_exhausted);
      reported += r->eviction->campaign_records;
      reported_outbox += r->eviction->outbox_rows;
    }
    ASSERT_LE(store.live_bytes(), kBudget) << "batch " << i;
  }
  ASSERT_GT(passes, 0u) << "the campaign records never passed the budget";
  EXPECT_EQ(reported_outbox, reported) << "campaign records are unsent outbox entries";

  // Every fault and alarm row and its unsent outbox entry is still there.
  const auto stats = store.stats();
  std::map<std::string, std::uint64_t> rows(stats.table_rows.begin(), stats.table_rows.end());
  EXPECT_EQ(rows["fault_events"], 2u * kBatches);
  EXPECT_EQ(rows["alarms"], 1u * kBatches);
  std::map<storage::OutboxKind, std::uint64_t> queued;
  std::set<std::int64_t> urgent, bulk;
  std::uint64_t report_total = 0, report_entries = 0;
  for (const auto& e : store.peek_outbox(1'000'000, std::size_t{1} << 30)) {
    ++queued[e.kind];
    if (e.kind == storage::OutboxKind::kCampaign) {
      v1::CampaignSamples rec;
      ASSERT_TRUE(rec.ParseFromArray(e.payload.data(), static_cast<int>(e.payload.size())));
      (rec.campaign_id() == "urgent" ? urgent : bulk).insert(rec.base_us());
    } else if (e.kind == storage::OutboxKind::kEvictionReport) {
      // The telemetry path's report, with the campaign records it dropped.
      const auto j = nlohmann::json::parse(std::string(e.payload.begin(), e.payload.end()));
      report_total += j["evicted"]["campaign"].get<std::uint64_t>();
      ++report_entries;
    }
  }
  EXPECT_EQ(queued[storage::OutboxKind::kFault], 2u * kBatches);
  EXPECT_EQ(queued[storage::OutboxKind::kAlarm], 1u * kBatches);
  EXPECT_EQ(report_entries, passes);
  EXPECT_EQ(report_total, reported);

  // The lower-priority campaign is evicted first: every record of the urgent one is kept...
  EXPECT_EQ(urgent.size(), static_cast<std::size_t>(kBatches));
  // ...and the bulk campaign lost its oldest records: what is left is its newest, contiguous.
  ASSERT_FALSE(bulk.empty());
  EXPECT_EQ(bulk.size() + reported, 3u * kBatches);
  EXPECT_EQ(*bulk.rbegin(), 3 * kBatches - 1);
  EXPECT_EQ(*bulk.begin(), static_cast<std::int64_t>(3 * kBatches - bulk.size()));

  // Counted (persisted) like the telemetry's evictions.
  std::uint64_t counted = 0;
  for (const auto& e : stats.evictions) {
    if (e.table == "campaign") counted = e.rows;
  }
  EXPECT_EQ(counted, reported);
}

TEST(CampaignEviction, TheStoreKeepsCampaignRecordsInTheirOwnPriorityRange) {
  testing::TempDir dir;
  storage::Store store(storage::StoreOptions{.path = (dir.path() / "range.db").string()});
  for (const int p : {5, 16}) {
    storage::Batch b;
    b.now_us = kDay0.count();
    b.messages.push_back({storage::OutboxKind::kCampaign, p, budget_record("x", 0, 10)});
    const auto r = store.write(b);
    ASSERT_FALSE(r.ok()) << p;
    EXPECT_NE(r.status().message.find("messages[0]"), std::string::npos) << r.status().message;
  }
  storage::Batch other;
  other.now_us = kDay0.count();
  other.messages.push_back({storage::OutboxKind::kInfo, 6, {1}});
  EXPECT_FALSE(store.write(other).ok()) << "6..15 belong to campaigns";
}

struct BudgetGateway {
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  CampaignServiceConfig config() const {
    CampaignServiceConfig c;
    c.trusted_keys = {{"eng", key.public_key().base64()}};
    c.vehicle_id = "bike-1";
    c.fleet_topic = "fleet/v1/campaigns";
    c.vehicle_topic = "fleet/v1/bike-1/campaigns";
    return c;
  }
  std::string signed_campaign(const std::string& id, int priority, std::uint64_t budget) const {
    auto c = test::base_campaign();
    c.set_id(id);
    c.set_priority(static_cast<std::uint32_t>(priority));
    c.set_disk_budget_bytes(budget);
    c.mutable_sampling()->set_period_ms(10);
    return sign_campaign(c, key, "eng");
  }
};

// Motor temperatures on the bus every 10 ms from `from` for `n` messages.
void feed_temps(CampaignService& service, Micros from, int n) {
  const auto& cat = motinova::Catalogue::standard();
  const motinova::DecodeOptions options;
  for (int i = 0; i < n; ++i) {
    const auto frame = motinova::MessageWriter(*cat.find("mc_status", 0x710), options)
                           .value("motor_temp_c", 40 + i % 20)
                           .frame();
    motinova::DecodedMessage m;
    motinova::decode(frame, cat, options, m);
    service.on_message(from + i * 10 * kMs, m);
  }
}

nlohmann::json budget_campaign_status(const CampaignService& service, Micros now, std::string_view id) {
  const auto status = service.status(now);  // kept: the loop reads into it
  for (const auto& c : status["campaigns"]) {
    if (c["id"] == id) return c;
  }
  return nullptr;
}

TEST(CampaignPriority, AMoreUrgentCampaignsRecordsGoFirstAndAcksCountPerPriority) {
  testing::TempDir dir;
  BudgetGateway gw;
  storage::Store store(storage::StoreOptions{.path = (dir.path() / "prio.db").string()});
  CampaignService service(gw.config(), store);
  // The bulk campaign is accepted and collects first; the urgent one second.
  ASSERT_TRUE(
      service
          .on_payload("fleet/v1/campaigns", gw.signed_campaign("bulk", 7, 1 << 20), 0, kDay0, kDay0)
          .accepted());
  ASSERT_TRUE(service
                  .on_payload("fleet/v1/campaigns", gw.signed_campaign("urgent", 1, 1 << 20), 0,
                              kDay0, kDay0)
                  .accepted());
  feed_temps(service, kDay0 + kSecond, 100);
  service.tick(kDay0 + 40 * kSecond, kDay0 + 40 * kSecond);
  auto messages = service.take_messages();
  ASSERT_EQ(messages.size(), 2u);
  std::map<int, std::size_t> by_priority;
  for (const auto& m : messages) by_priority[m.priority] += m.payload.size();
  ASSERT_EQ(by_priority.size(), 2u);
  EXPECT_TRUE(by_priority.contains(6 + 1));
  EXPECT_TRUE(by_priority.contains(6 + 7));
  // Queued in that order (bulk first), the urgent campaign's record is sent first.
  std::stable_sort(messages.begin(), messages.end(),
                   [](const auto& a, const auto& b) { return a.priority > b.priority; });
  storage::Batch batch;
  batch.now_us = (kDay0 + 40 * kSecond).count();
  batch.messages = messages;
  ASSERT_TRUE(store.write(batch).ok());
  const auto peeked = store.peek_outbox(1, 1 << 20);
  ASSERT_EQ(peeked.size(), 1u);
  v1::CampaignSamples first;
  ASSERT_TRUE(
      first.ParseFromArray(peeked[0].payload.data(), static_cast<int>(peeked[0].payload.size())));
  EXPECT_EQ(first.campaign_id(), "urgent");

  // Its acknowledgement frees the urgent campaign's budget, not the bulk one's.
  const auto before_bulk = budget_campaign_status(service, kDay0, "bulk")["bytes_in_store"];
  ASSERT_GT(before_bulk.get<std::uint64_t>(), 0u);
  const std::uint64_t seq = peeked[0].seq;
  ASSERT_EQ(store.ack(std::span(&seq, 1)).value_or(0), 1u);
  service.store_holds(store.outbox_depth());
  EXPECT_EQ(budget_campaign_status(service, kDay0, "urgent")["bytes_in_store"], 0u);
  EXPECT_EQ(budget_campaign_status(service, kDay0, "bulk")["bytes_in_store"], before_bulk);
}

TEST(CampaignBudget, ARestartedBikeDoesNotGrantACampaignAFreshBudget) {
  testing::TempDir dir;
  BudgetGateway gw;
  const std::string path = (dir.path() / "restart.db").string();
  constexpr std::uint64_t kBudget = 4096;
  const std::uint64_t fresh = kBudget / 27;  // samples a fresh budget admits at most
  std::uint64_t in_store = 0;
  {
    storage::Store store(storage::StoreOptions{.path = path});
    CampaignService service(gw.config(), store);
    ASSERT_TRUE(service
                    .on_payload("fleet/v1/campaigns", gw.signed_campaign("tiny", 3, kBudget), 0,
                                kDay0, kDay0)
                    .accepted());
    feed_temps(service, kDay0 + kSecond, 1000);  // 10 s at 100 Hz: far over its budget
    service.tick(kDay0 + 40 * kSecond, kDay0 + 40 * kSecond);
    storage::Batch batch;
    batch.now_us = (kDay0 + 40 * kSecond).count();
    batch.messages = service.take_messages();
    ASSERT_EQ(batch.messages.size(), 1u);
    ASSERT_TRUE(store.write(batch).ok());
    const auto st = budget_campaign_status(service, kDay0 + 40 * kSecond, "tiny");
    in_store = st["bytes_in_store"].get<std::uint64_t>();
    ASSERT_EQ(in_store, batch.messages[0].payload.size());
    EXPECT_GT(st["dropped"].get<std::uint64_t>(), 0u);
  }
  // Restarted, broker down: the record is still unsent, and still counts.
  storage::Store store(storage::StoreOptions{.path = path});
  CampaignService service(gw.config(), store);
  service.restore(kDay0 + 50 * kSecond, kDay0 + 50 * kSecond);
  ASSERT_EQ(service.size(), 1u);
  EXPECT_EQ(budget_campaign_status(service, kDay0 + 50 * kSecond, "tiny")["bytes_in_store"], in_store);
  feed_temps(service, kDay0 + 60 * kSecond, 1000);
  const auto st = budget_campaign_status(service, kDay0 + 80 * kSecond, "tiny");
  const std::uint64_t admitted = st["samples"].get<std::uint64_t>();
  EXPECT_GT(admitted, 0u);
  EXPECT_LE(admitted * 27 + in_store, kBudget) << "only what is left of its budget";
  EXPECT_LT(admitted, fresh);
  EXPECT_GT(st["dropped"].get<std::uint64_t>(), 0u);
}

}  // namespace
}  // namespace fleetgw::campaign
