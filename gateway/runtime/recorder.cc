#include "gateway/runtime/recorder.h"

#include <spdlog/spdlog.h>

namespace fleetgw::runtime {
namespace {

Micros ms(int64_t v) {
  return Micros(v * 1000);
}

// Appends every record of `from` to `to` (used to retry a failed batch together with new ones).
void append(storage::Batch& to, storage::Batch&& from) {
  auto move_all = [](auto& dst, auto& src) {
    for (auto& x : src) dst.push_back(std::move(x));
  };
  move_all(to.telemetry, from.telemetry);
  move_all(to.rides, from.rides);
  move_all(to.faults, from.faults);
  move_all(to.packs, from.packs);
  move_all(to.locks, from.locks);
  move_all(to.command_results, from.command_results);
  move_all(to.commands, from.commands);
  move_all(to.messages, from.messages);
  move_all(to.meta, from.meta);
  to.now_us = from.now_us;
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
  d.apply(c.protocol);
  return d;
}

storage::StoreOptions make_store_options(const config::Config& c) {
  storage::StoreOptions o;
  o.path = c.storage.path;
  o.max_bytes = static_cast<uint64_t>(c.storage.max_mb) * 1024 * 1024;
  o.durability =
      c.storage.synchronous == "full" ? storage::Durability::kFull : storage::Durability::kNormal;
  return o;
}

Recorder::Recorder(const config::Config& config, storage::Store& store, Micros now,
                   WallClock wall_clock)
    : store_(store),
      trackers_(make_domain_config(config), sink_),
      flush_interval_(std::chrono::milliseconds(config.storage.flush_ms)),
      wall_clock_(wall_clock ? std::move(wall_clock) : WallClock(&std::chrono::steady_clock::now)) {
  const auto open = store_.open_rides();
  if (!open.empty()) {
    spdlog::info("resuming {} open ride(s) from the previous run", open.size());
  }
  trackers_.restore(open, now);
  last_now_ = now;
  note_pending();
}

Recorder::~Recorder() {
  try {
    flush(last_now_);
  } catch (const std::exception& e) {
    spdlog::error("final flush failed: {}", e.what());
  }
}

void Recorder::note_pending() {
  if (!pending_since_ && !(sink_.empty() && pending_.empty())) pending_since_ = wall_clock_();
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
  const auto due = flush_deadline();
  if (urgent() || (due && wall_clock_() >= *due)) flush(last_now_);
}

bool Recorder::urgent() const {
  // Interim (contract C, H-storage owns the real policy): anything but telemetry is urgent.
  const storage::Batch& b = sink_.batch();
  const std::size_t n = b.size();
  return n != b.telemetry.size() || n >= 4096;
}

std::optional<std::chrono::steady_clock::time_point> Recorder::flush_deadline() const {
  if (!pending_since_) return std::nullopt;
  return *pending_since_ + flush_interval_;
}

storage::StorageHealth Recorder::health() const {
  storage::StorageHealth h;
  h.failing = !pending_.empty();
  h.failed_writes = failures_;
  return h;
}

FlushOutcome Recorder::flush(Micros now) {
  FlushOutcome out;
  if (!sink_.empty()) append(pending_, sink_.take(now));
  if (pending_.empty()) {
    pending_since_.reset();
    return out;
  }
  pending_.now_us = now.count();
  out.records = pending_.size();
  try {
    const auto result = store_.write(pending_);
    ++batches_;
    if (result.eviction) {
      spdlog::warn("storage budget reached: evicted {} telemetry and {} pack rows",
                   result.eviction->telemetry_rows, result.eviction->pack_snapshot_rows);
    }
    pending_.clear();
    pending_since_.reset();
    if (after_flush_) after_flush_();
  } catch (const std::invalid_argument& e) {
    // A record the store refuses is a bug upstream; keeping it would block every later batch.
    ++failures_;
    out.failed = true;
    spdlog::error("storage refused a batch of {} records: {}", pending_.size(), e.what());
    pending_.clear();
    pending_since_.reset();
  } catch (const std::exception& e) {
    ++failures_;
    out.failed = true;
    pending_since_ = wall_clock_();  // retried one interval later
    spdlog::error("storage write failed ({} records kept for the next attempt): {}",
                  pending_.size(), e.what());
  }
  return out;
}

}  // namespace fleetgw::runtime
