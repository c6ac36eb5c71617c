#include "gateway/runtime/recorder.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/domain/payloads.h"
#include "gateway/runtime/clock_units.h"

namespace fleetgw::runtime {
namespace {

// Moves every element of `src` to the end of `dst`. Into an empty `dst` the two buffers swap:
// the records are not moved one by one, and `src` (the sink, refilled at once) gets back the
// capacity `dst` kept from the last batch instead of growing from nothing again.
template <typename V>
void move_all(V& dst, V& src) {
  if (dst.empty()) {
    dst.swap(src);
  } else {
    for (auto& x : src) dst.push_back(std::move(x));
  }
  src.clear();
}

// Appends every record of `from` to `to` (a failed batch is retried together with new ones).
void append(storage::Batch& to, storage::Batch& from) {
  move_all(to.telemetry, from.telemetry);
  move_all(to.rides, from.rides);
  move_all(to.faults, from.faults);
  move_all(to.packs, from.packs);
  move_all(to.locks, from.locks);
  move_all(to.alarms, from.alarms);
  move_all(to.zone_events, from.zone_events);
  move_all(to.command_results, from.command_results);
  move_all(to.commands, from.commands);
  move_all(to.messages, from.messages);
  move_all(to.meta, from.meta);
  to.now_us = from.now_us;
}

// Anything the store never evicts (or that is not telemetry at all): worth a commit at once.
bool has_non_telemetry(const storage::Batch& b) {
  return !b.rides.empty() || !b.faults.empty() || !b.packs.empty() || !b.locks.empty() ||
         !b.alarms.empty() || !b.zone_events.empty() || !b.command_results.empty() ||
         !b.commands.empty() || !b.messages.empty() || !b.meta.empty();
}

template <typename T>
std::size_t footprint(const storage::PendingRow<T>& p) {
  return sizeof(p) + (p.uplink ? p.uplink->capacity() : 0);
}
// A ride carries its track text (schema v6): tens of kB for a long ride.
std::size_t footprint(const storage::PendingRow<storage::RideRow>& p) {
  return sizeof(p) + (p.uplink ? p.uplink->capacity() : 0) +
         (p.record.track ? p.record.track->capacity() : 0);
}

// Heap held by a batch, roughly (records plus payloads), for the retry-memory bound.
std::size_t footprint(const storage::Batch& b) {
  std::size_t n = 0;
  for (const auto& x : b.telemetry) n += footprint(x);
  for (const auto& x : b.rides) n += footprint(x);
  for (const auto& x : b.faults) n += footprint(x);
  for (const auto& x : b.packs) n += footprint(x) + x.record.lifetime_json.size();
  for (const auto& x : b.locks) n += footprint(x);
  for (const auto& x : b.alarms) n += footprint(x) + x.record.detail.capacity();
  for (const auto& x : b.zone_events) n += footprint(x) + x.record.zone_name.capacity();
  for (const auto& x : b.command_results) n += footprint(x);
  n += b.commands.size() * sizeof(storage::CommandJournalRow);
  for (const auto& m : b.messages) n += sizeof(m) + m.payload.capacity();
  n += b.meta.size() * 64;
  return n;
}

// Drops the oldest entries of `v` until `bytes` <= `limit`; returns how many were dropped.
template <typename V>
std::size_t drop_oldest(V& v, std::size_t& bytes, std::size_t limit) {
  std::size_t n = 0;
  while (n < v.size() && bytes > limit) {
    const std::size_t size = [&] {
      if constexpr (requires { v[n].uplink; }) {
        return footprint(v[n]);
      } else {
        return sizeof(v[n]);
      }
    }();
    bytes -= std::min(bytes, size);
    ++n;
  }
  v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n));
  return n;
}

}  // namespace

domain::DomainConfig make_domain_config(const config::Config& c) {
  domain::DomainConfig d;
  d.ride.moving_speed_kmh = c.ride.moving_speed_kmh;
  d.ride.stationary_end = Micros(int64_t{c.ride.stationary_end_s} * 1'000'000);
  d.ride.mc_offline_timeout = ms(c.node.offline_timeout_ms);
  d.faults.debounce = ms(c.faults.debounce_ms);
  d.faults.stale = ms(c.node.fault_stale_ms);
  d.telemetry.riding_interval = ms(c.telemetry.riding_interval_ms);
  d.telemetry.parked_interval = ms(c.telemetry.parked_interval_ms);
  d.alarms.enabled = c.alarms.enabled;
  d.alarms.movement_speed_kmh = c.alarms.movement_speed_kmh;
  d.alarms.movement_rpm = c.alarms.movement_rpm;
  d.alarms.movement_debounce = ms(c.alarms.movement_debounce_ms);
  d.alarms.movement_clear = Micros(int64_t{c.alarms.movement_clear_s} * 1'000'000);
  d.alarms.low_battery_pct = c.alarms.low_battery_pct;
  d.alarms.low_battery_hysteresis_pct = c.alarms.low_battery_hysteresis_pct;
  d.alarms.battery_silent = ms(c.alarms.battery_silent_ms);
  d.apply(c.protocol);
  return d;
}

storage::StoreOptions make_store_options(const config::Config& c) {
  storage::StoreOptions o;
  o.path = c.storage.path;
  o.max_bytes = static_cast<uint64_t>(c.storage.max_mb) * 1024 * 1024;
  o.durability =
      c.storage.synchronous == "full" ? storage::Durability::kFull : storage::Durability::kNormal;
  // Eviction reports are stored as the fleetgw.v1.EvictionReport they are published as.
  o.encode_eviction_report = domain::eviction_report_payload;
  return o;
}

Recorder::Recorder(const config::Config& config, storage::Store& store, Micros now,
                   Env& env)
    : store_(store),
      trackers_(make_domain_config(config), sink_),
      env_(&env),
      flush_interval_(std::chrono::milliseconds(config.storage.flush_ms)),
      error_log_(nullptr, std::chrono::seconds(10), env),
      drop_log_(nullptr, std::chrono::seconds(10), env) {
  const auto open = store_.open_rides();
  if (!open.empty()) {
    spdlog::info("resuming {} open ride(s) from the previous run", open.size());
  }
  trackers_.restore(open, now);
  if (auto serial = store_.meta(domain::AlarmTracker::kBmsSerialMetaKey)) {
    trackers_.restore_bms_serial(std::move(*serial));
  }
  note_pending();
  last_now_ = now;
}

Recorder::~Recorder() {
  try {
    const auto outcome = flush(last_now_);
    if (!outcome.status.ok()) {
      spdlog::error("storage: {} record(s) could not be written before stopping: {}",
                    pending_records(), last_error_);
    }
  } catch (const std::exception& e) {
    spdlog::error("final flush failed: {}", e.what());
  }
}

std::chrono::steady_clock::time_point Recorder::wall() const {
  return env_->steady_now();
}

void Recorder::note_pending() {
  if (!first_pending_ && !sink_.empty()) first_pending_ = wall();
}

void Recorder::on_message(const motinova::DecodedMessage& message, Micros now) {
  last_now_ = std::max(last_now_, now);
  trackers_.on_message(message, last_now_);
  note_pending();
}

void Recorder::tick(Micros now) {
  last_now_ = std::max(last_now_, now);
  trackers_.tick(last_now_);
  note_pending();
  if (!flush_on_tick_) return;
  const auto w = wall();
  if (tick_retry_.waiting(w)) return;  // failing: wait for the retry interval
  const auto deadline = flush_deadline();
  if (urgent() || (deadline && w >= *deadline)) {
    if (!flush(last_now_).status.ok()) {
      tick_retry_.failed(w);
    } else {
      tick_retry_.succeeded();
    }
    checkpoint_if_due();
  }
}

void Recorder::checkpoint_if_due() {
  store_.checkpoint_if_due();
}

void Recorder::queue_message(storage::UplinkMessage message) {
  sink_.batch().messages.push_back(std::move(message));
  note_pending();
}

void Recorder::record_alarm(storage::AlarmRow record, storage::Bytes payload) {
  sink_.batch().alarms.push_back({std::move(record), std::move(payload)});
  note_pending();
}

void Recorder::record_zone_event(storage::ZoneEventRow record, storage::Bytes payload) {
  sink_.batch().zone_events.push_back({std::move(record), std::move(payload)});
  note_pending();
}

bool Recorder::urgent() const {
  if (pending_records() == 0) return false;
  const auto& b = sink_.batch();
  return has_non_telemetry(b) || has_non_telemetry(retry_) || b.size() >= kMaxBatchRecords;
}

std::optional<std::chrono::steady_clock::time_point> Recorder::flush_deadline() const {
  if (pending_records() == 0) return std::nullopt;
  if (first_pending_) return *first_pending_ + flush_interval_;
  return wall();
}

FlushOutcome Recorder::flush(Micros now) {
  FlushOutcome out;
  if (!sink_.empty()) {
    append(retry_, sink_.batch());
  }
  first_pending_.reset();
  if (retry_.empty()) return out;
  retry_.now_us = now.count();
  const auto result = store_.write(retry_);
  if (result.ok()) {
    ++batches_;
    out.records = retry_.size();
    retry_.clear();
    if (last_flush_failed_) error_log_.resolved("storage: pending records written, storage OK");
    last_flush_failed_ = false;
    failing_since_us_ = 0;
    if (after_flush_) after_flush_();
    return out;
  }

  ++failures_;
  if (!last_flush_failed_) failing_since_us_ = env_->wall_now().count();
  last_flush_failed_ = true;
  last_error_ = store_.health().last_error;
  const Status error = result.status();
  if (error.code == StatusCode::kInvalid) {
    // A record the store refuses is a bug upstream; keeping it would block every later batch.
    error_log_.report("storage: refused a batch (dropped): " + error.message);
    dropped_ += retry_.size();
    retry_.clear();
    return out;
  }
  out.status = error;  // records kept: retried by the caller's back-off
  error_log_.report("storage: write failed, records kept in memory for a retry: " + last_error_);
  if (error.code == StatusCode::kFull &&
      (!retry_.telemetry.empty() || !retry_.packs.empty()) && has_non_telemetry(retry_)) {
    const auto first = write_without_evictable(now);
    out.records += first.records;
  }
  bound_retry_memory();
  return out;
}

// On a full disk: the records that are never evicted go first, without the telemetry and pack
// snapshots that may be what no longer fits.
FlushOutcome Recorder::write_without_evictable(Micros now) {
  FlushOutcome out;
  storage::Batch evictable;
  evictable.telemetry = std::exchange(retry_.telemetry, {});
  evictable.packs = std::exchange(retry_.packs, {});
  retry_.now_us = now.count();
  const auto result = store_.write(retry_);
  if (result.ok()) {
    out.records = retry_.size();
    retry_.clear();
    if (after_flush_) after_flush_();
  } else {
    out.status = result.status();
  }
  append(retry_, evictable);
  return out;
}

void Recorder::bound_retry_memory() {
  std::size_t bytes = footprint(retry_);
  if (bytes <= retry_memory_bytes_) return;
  std::size_t dropped = 0;
  // Cheapest loss first; never beyond the soft bound for what is never evicted.
  dropped += drop_oldest(retry_.telemetry, bytes, retry_memory_bytes_);
  dropped += drop_oldest(retry_.packs, bytes, retry_memory_bytes_);
  dropped += drop_oldest(retry_.locks, bytes, retry_memory_bytes_);
  dropped += drop_oldest(retry_.rides, bytes, retry_memory_bytes_);
  const std::size_t hard = retry_memory_bytes_ * 4;
  if (bytes > hard) {
    dropped += drop_oldest(retry_.messages, bytes, hard);
    dropped += drop_oldest(retry_.meta, bytes, hard);
    dropped += drop_oldest(retry_.faults, bytes, hard);
    dropped += drop_oldest(retry_.commands, bytes, hard);
    dropped += drop_oldest(retry_.alarms, bytes, hard);
    dropped += drop_oldest(retry_.zone_events, bytes, hard);
    dropped += drop_oldest(retry_.command_results, bytes, hard);
  }
  if (dropped == 0) return;
  dropped_ += dropped;
  drop_log_.report(
      "storage: memory for records waiting to be written is full; dropping the oldest "
      "telemetry first (dropped records are counted in status)");
}

storage::StorageHealth Recorder::health() const {
  storage::StorageHealth h = store_.health();
  if (last_flush_failed_) {
    if (!h.failing) {
      h.failing = true;
      h.failing_since_us = failing_since_us_;
    }
    if (h.last_error.empty()) h.last_error = last_error_;
  }
  h.dropped_records = dropped_;
  h.pending_records = pending_records();
  return h;
}

}  // namespace fleetgw::runtime
