// The disk budget: how it is split (WAL, shm, reserve, data), eviction when the live pages pass
// the evictable limit, eviction after SQLITE_FULL, and WAL checkpoints (storage/store.h).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <limits>

#include "storage/store_impl.h"

namespace fleetgw::storage {
namespace {

constexpr std::uint64_t kKiB = 1024;
constexpr std::uint64_t kMiB = 1024 * 1024;
constexpr std::uint64_t kWalFrameHeader = 24;

struct EvictableTable {
  std::string_view table;
  OutboxKind kind;
  OutboxPriority priority;  // each evictable kind has a priority of its own
};
// Eviction order: cheapest loss first.
constexpr std::array<EvictableTable, 2> kEvictionOrder = {{
    {"telemetry", OutboxKind::kTelemetry, OutboxPriority::kTelemetry},
    {"pack_snapshots", OutboxKind::kPack, OutboxPriority::kPack},
}};

// Deletes the unsent outbox entries of `evicted`'s rows with id <= cutoff; returns how many.
// Without an index on source_id: the entries of one kind sit under their priority in
// `outbox_by_priority`, queued in the order of their rows, so the evicted rows' entries are the
// oldest there. The scan walks them up to the first entry of a row that stays, and touches
// nothing else (a unit days offline holds most of its outbox under the same priority).
std::uint64_t delete_queued_entries(Database& db, const EvictableTable& evicted,
                                    std::int64_t cutoff) {
  auto st = db.cached(
      "DELETE FROM outbox INDEXED BY outbox_by_priority "
      "WHERE priority = ?1 AND kind = ?2 AND source_id <= ?3 AND seq < coalesce("
      "(SELECT seq FROM outbox INDEXED BY outbox_by_priority "
      "WHERE priority = ?1 AND kind = ?2 AND source_id > ?3 ORDER BY seq LIMIT 1), "
      "9223372036854775807)");
  st->bind_all(static_cast<int>(evicted.priority), to_string(evicted.kind), cutoff);
  st->run();
  return static_cast<std::uint64_t>(db.changes());
}

// Campaign records (issue 29) have no table row: each is one outbox entry of kind `campaign` at
// priorities kCampaign (6) .. kLowestCampaignPriority (15), where nothing else is queued. They
// are evicted after telemetry -- the unbounded filler, while each campaign's records are bounded
// by its own disk budget and all of them by a quarter of the store's -- and before pack
// snapshots and every record that is never evicted (faults, alarms, rides...): the lowest
// campaign priority first (the highest number), oldest first within it. Deletes at most
// `max_entries`, stopping once `bytes` of payload are gone; returns how many entries.
std::uint64_t evict_campaign_records(Database& db, std::uint64_t bytes, std::int64_t max_entries) {
  auto pick = db.cached(
      "SELECT seq, length(payload) FROM outbox INDEXED BY outbox_by_priority "
      "WHERE priority = ? ORDER BY seq LIMIT ?");
  auto del = db.cached(
      "DELETE FROM outbox INDEXED BY outbox_by_priority WHERE priority = ?2 AND seq <= ?1");
  std::uint64_t evicted = 0, freed = 0;
  for (int p = kLowestCampaignPriority;
       p >= static_cast<int>(OutboxPriority::kCampaign) && freed < bytes && max_entries > 0; --p) {
    std::optional<std::int64_t> cutoff;
    std::int64_t n = 0;
    pick->bind_all(p, max_entries);
    while (freed < bytes && pick->step()) {
      cutoff = pick->column_int64(0);
      freed += static_cast<std::uint64_t>(pick->column_int64(1));
      ++n;
    }
    pick->reset();
    if (!cutoff) continue;
    del->bind_all(*cutoff, p);
    del->run();
    del->reset();
    evicted += static_cast<std::uint64_t>(db.changes());
    max_entries -= n;
  }
  return evicted;
}

void count_eviction(Database& db, std::string_view name, std::uint64_t rows, std::int64_t now_us) {
  // Upsert: stores created before campaigns have no 'campaign' row.
  auto st = db.cached(
      "INSERT INTO eviction_counters (table_name, rows, passes, last_us) VALUES (?1, ?2, 1, ?3) "
      "ON CONFLICT (table_name) DO UPDATE SET rows = rows + ?2, passes = passes + 1, "
      "last_us = ?3");
  st->bind_all(name, static_cast<std::int64_t>(rows), now_us);
  st->run();
}

}  // namespace

BudgetPlan plan_budget(std::uint64_t configured, std::uint64_t effective, std::uint64_t page_size,
                       int wal_pages_override) {
  BudgetPlan p;
  p.configured = configured;
  p.effective = effective;
  const std::uint64_t frame = std::max<std::uint64_t>(page_size, 512) + kWalFrameHeader;
  p.wal_allowance = effective == 0 ? 4 * kMiB : std::clamp(effective / 8, 64 * kKiB, 4 * kMiB);
  if (wal_pages_override > 0)
    p.wal_allowance = static_cast<std::uint64_t>(wal_pages_override) * frame;
  p.wal_pages = std::max<std::uint64_t>(p.wal_allowance / frame, 8);
  if (effective > 0) {
    // SQLite's -shm index: 32 KiB per 4096 WAL frames.
    p.shm_allowance = 32 * kKiB * (p.wal_pages / 4096 + 1);
    const std::uint64_t overhead = p.wal_allowance + p.shm_allowance;
    const std::uint64_t data = effective > overhead ? effective - overhead : 0;
    p.reserve = std::min(data / 10, 2 * kMiB);
  }
  return p;
}

std::uint64_t BudgetPlan::data_limit() const {
  if (effective == 0) return std::numeric_limits<std::uint64_t>::max();
  const std::uint64_t overhead = wal_allowance + shm_allowance;
  return effective > overhead ? effective - overhead : 0;
}

std::uint64_t BudgetPlan::evictable_limit() const {
  const std::uint64_t data = data_limit();
  if (effective == 0) return data;
  return data > reserve ? data - reserve : 0;
}

std::uint64_t Store::Impl::live_bytes() {
  std::int64_t page_count, freelist, size;
  {
    auto st = db.cached("PRAGMA page_count");
    st->step();
    page_count = st->column_int64(0);
  }
  {
    auto st = db.cached("PRAGMA freelist_count");
    st->step();
    freelist = st->column_int64(0);
  }
  {
    auto st = db.cached("PRAGMA page_size");
    st->step();
    size = st->column_int64(0);
  }
  return static_cast<std::uint64_t>(std::max<std::int64_t>(page_count - freelist, 0) * size);
}

std::optional<EvictionPass> Store::Impl::enforce_budget(std::int64_t now_us, Statement& outbox,
                                                          std::uint64_t& seq) {
  if (budget.effective == 0) return std::nullopt;
  const std::uint64_t limit = budget.evictable_limit();
  std::uint64_t live = live_bytes();
  if (live <= limit) {
    budget_exhausted_logged = false;
    return std::nullopt;
  }

  EvictionPass report;
  report.at_us = now_us;
  report.budget_bytes = limit;
  report.bytes_before = live;
  const auto target = static_cast<std::uint64_t>(static_cast<double>(limit) * options.low_water);

  for (const EvictableTable& evictable : kEvictionOrder) {
    if (evictable.kind == OutboxKind::kPack && live > target) {
      // Campaign records go after telemetry, before pack snapshots (evict_campaign_records).
      std::uint64_t evicted = 0;
      while (live > target) {
        const std::uint64_t n = evict_campaign_records(db, live - target, 100'000);
        if (n == 0) break;
        evicted += n;
        live = live_bytes();
      }
      if (evicted > 0) {
        report.campaign_records = evicted;
        report.outbox_rows += evicted;
        count_eviction(db, "campaign", evicted, now_us);
      }
    }
    const std::string t(evictable.table);
    auto cutoff_st = db.cached("SELECT id FROM " + t + " ORDER BY id LIMIT 1 OFFSET ?");
    auto max_st = db.cached("SELECT max(id) FROM " + t);
    auto delete_st = db.cached("DELETE FROM " + t + " WHERE id <= ?");
    std::uint64_t evicted = 0;
    while (live > target) {
      // Delete in chunks sized from the excess (rows are ~100-200 bytes with their outbox
      // entry) and re-measure: SQLite frees a page only once it is empty.
      const std::uint64_t excess = live - target;
      const std::int64_t chunk =
          std::clamp<std::int64_t>(static_cast<std::int64_t>(excess / 128), 64, 100'000);
      std::optional<std::int64_t> cutoff;
      cutoff_st->bind(1, chunk - 1);
      if (cutoff_st->step()) cutoff = cutoff_st->column_int64(0);
      cutoff_st->reset();
      if (!cutoff) {
        if (max_st->step()) cutoff = max_st->column_opt_int64(0);
        max_st->reset();
      }
      if (!cutoff) break;  // table empty
      delete_st->bind(1, *cutoff);
      delete_st->run();
      delete_st->reset();
      evicted += static_cast<std::uint64_t>(db.changes());
      report.outbox_rows += delete_queued_entries(db, evictable, *cutoff);
      live = live_bytes();
    }
    (evictable.kind == OutboxKind::kTelemetry ? report.telemetry_rows : report.pack_snapshot_rows) =
        evicted;
    if (evicted > 0) {
      auto st = db.cached(
          "UPDATE eviction_counters SET rows = rows + ?, passes = passes + 1, last_us = ? "
          "WHERE table_name = ?");
      st->bind_all(static_cast<std::int64_t>(evicted), now_us, evictable.table);
      st->run();
    }
  }
  if (report.outbox_rows > 0) {
    auto st = db.cached(
        "UPDATE eviction_counters SET rows = rows + ?, passes = passes + 1, last_us = ? "
        "WHERE table_name = 'outbox'");
    st->bind_all(static_cast<std::int64_t>(report.outbox_rows), now_us);
    st->run();
  }
  const bool evicted_any =
      report.telemetry_rows + report.pack_snapshot_rows + report.campaign_records > 0;
  if (evicted_any) {
    // Give the freed pages back to the file system (the file shrinks at the next checkpoint).
    auto st = db.cached("PRAGMA incremental_vacuum");
    st->run();
  }
  report.bytes_after = live_bytes();
  // Over the whole data budget (reserve included) with nothing left to evict.
  report.budget_exhausted = report.bytes_after > budget.data_limit();
  {
    auto st = db.cached("SELECT ts_us FROM telemetry ORDER BY id LIMIT 1");
    if (st->step()) report.oldest_telemetry_kept_us = st->column_int64(0);
  }
  if (report.budget_exhausted && !budget_exhausted_logged) {
    log->error(
        "storage: '{}' is over its {} B budget with no telemetry, campaign records or pack "
        "snapshots left to evict ({} B of faults, rides, lock events, commands and unsent outbox); "
        "raise max_mb or get the unit online",
        options.path, budget.effective, report.bytes_after);
  }
  const bool first_exhaustion = report.budget_exhausted && !budget_exhausted_logged;
  budget_exhausted_logged = report.budget_exhausted;
  if (!evicted_any && !first_exhaustion) return std::nullopt;

  if (options.encode_eviction_report) {
    const Bytes payload = options.encode_eviction_report(report, seq);
    enqueue(outbox, OutboxKind::kEvictionReport, kEvictionReportPriority, payload, std::nullopt,
            now_us, seq);
  } else {
    const std::string payload = report.to_json();
    enqueue(outbox, OutboxKind::kEvictionReport, kEvictionReportPriority,
            std::span(reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()),
            std::nullopt, now_us, seq);
  }
  return report;
}

std::uint64_t Store::Impl::evict_for_space(std::int64_t now_us, int attempt) {
  // Restart the WAL first (its file space is reused from the beginning; truncating it would
  // hand that space to whoever filled the disk).
  checkpoint(SQLITE_CHECKPOINT_RESTART);
  try {
    Transaction tx(db);
    std::uint64_t evicted = 0;
    for (const EvictableTable& evictable : kEvictionOrder) {
      if (evictable.kind == OutboxKind::kPack) {
        // Campaign records after telemetry, before pack snapshots: a quarter of them per
        // attempt (growing), at least 16 entries (each up to ~30 KB).
        const std::int64_t entries =
            db.query_int64("SELECT count(*) FROM outbox WHERE priority >= " +
                           std::to_string(static_cast<int>(OutboxPriority::kCampaign)))
                .value_or(0);
        if (entries > 0) {
          const std::int64_t chunk =
              std::min<std::int64_t>(entries, std::max<std::int64_t>(16, entries * attempt / 4));
          evicted = evict_campaign_records(db, std::numeric_limits<std::uint64_t>::max(), chunk);
          count_eviction(db, "campaign", evicted, now_us);
          log->warn("storage: disk full on '{}': evicted {} unsent campaign records to make room",
                    options.path, evicted);
          break;
        }
      }
      const std::string t(evictable.table);
      const std::int64_t rows = db.query_int64("SELECT count(*) FROM " + t).value_or(0);
      if (rows == 0) continue;
      // A quarter of the table, growing with each attempt, at least 256 rows.
      const std::int64_t chunk =
          std::min<std::int64_t>(rows, std::max<std::int64_t>(256, rows * attempt / 4));
      std::optional<std::int64_t> cutoff;
      {
        auto st = db.cached("SELECT id FROM " + t + " ORDER BY id LIMIT 1 OFFSET ?");
        st->bind(1, chunk - 1);
        if (st->step()) cutoff = st->column_int64(0);
      }
      if (!cutoff) continue;
      {
        auto st = db.cached("DELETE FROM " + t + " WHERE id <= ?");
        st->bind(1, *cutoff);
        st->run();
        evicted += static_cast<std::uint64_t>(db.changes());
      }
      const std::uint64_t outbox_rows = delete_queued_entries(db, evictable, *cutoff);
      auto st = db.cached(
          "UPDATE eviction_counters SET rows = rows + ?, passes = passes + 1, last_us = ? "
          "WHERE table_name = ?");
      st->bind_all(static_cast<std::int64_t>(evicted), now_us, evictable.table);
      st->run();
      auto& summary = disk_full_evictions;
      summary.rows += evicted;
      ++summary.passes;
      const auto wall = options.env->steady_now();
      if (!summary.last_logged) {
        log->warn("storage: disk full on '{}': evicted {} {} rows ({} unsent) to make room",
                  options.path, evicted, evictable.table, outbox_rows);
        summary = {wall, 0, 0};
      } else if (wall - *summary.last_logged >= std::chrono::seconds(10)) {
        log->warn(
            "storage: disk full on '{}': evicted {} more rows in {} passes over the last {} s",
            options.path, summary.rows, summary.passes,
            std::chrono::duration_cast<std::chrono::seconds>(wall - *summary.last_logged).count());
        summary = {wall, 0, 0};
      }
      break;  // one table per attempt: telemetry first, pack snapshots once it is empty
    }
    if (evicted == 0) return 0;
    tx.commit();
    return evicted;
  } catch (const std::exception& e) {
    log->debug("storage: eviction after a full disk failed: {}", e.what());
    return 0;
  }
}

bool Store::Impl::checkpoint(int mode) {
  if (options.read_only) return false;
  // One connection checkpoints at a time: let the background one finish (this thread appends
  // no frames meanwhile), so that this checkpoint can copy what is left.
  if (checkpointer) checkpointer->wait_until_idle();
  // Never wait for a reader (a technician's `fleetgw db` may hold an old snapshot): a busy
  // checkpoint copies what it can and is retried later.
  sqlite3_busy_timeout(db.handle(), 0);
  int log_frames = 0, done = 0;
  const int rc = sqlite3_wal_checkpoint_v2(db.handle(), nullptr, mode, &log_frames, &done);
  sqlite3_busy_timeout(db.handle(), 5000);
  if (rc == SQLITE_OK && log_frames == done) {
    wal_frames = 0;
    return true;
  }
  return false;
}

bool Store::checkpoint_if_due() {
  if (impl_->wal_frames < std::max<std::uint64_t>(impl_->budget.wal_pages / 2, 1)) return false;
  if (impl_->checkpointer) {
    // The checkpoint (and its fsyncs) runs on the checkpointer's thread, PASSIVE: the caller
    // (the event loop) never waits for it. The WAL's allowance is part of the disk budget;
    // once every frame is copied the next commit restarts the WAL from its start (reusing its
    // file space rather than truncating and growing it again), and journal_size_limit (= that
    // allowance, set at open) still cuts a WAL that one big commit made larger.
    impl_->checkpointer->request();
    // Asked once per commit: until the next commit reports the WAL's size again (wal hook),
    // repeated calls (one per settle of the event loop) do not queue redundant checkpoints.
    impl_->wal_frames = 0;
    return true;
  }
  return impl_->checkpoint(SQLITE_CHECKPOINT_RESTART);  // read-only or in-memory
}

CheckpointCounters Store::checkpoint_counters() const {
  return impl_->checkpointer ? impl_->checkpointer->counters() : CheckpointCounters{};
}

}  // namespace fleetgw::storage
