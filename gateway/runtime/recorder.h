// Recorder: the storage stage of the pipeline. It feeds every decoded message to the domain
// trackers and writes what they produce to the SQLite store, many records per transaction
// (group commit by size and by wall-clock time).
//
// Contract:
//  * Single-threaded. Bus time (`now`, simulated or replayed) only goes into the records; when
//    to write is decided on the WALL clock injected at construction (default steady_clock), so
//    a replay at 1000x still commits about once per storage.flush_ms of real time, not 1000x as
//    often.
//  * urgent(): a pending record is not telemetry (command results, faults, rides, locks, pack
//    snapshots, journal...) or the pending batch reached kMaxBatchRecords: the pipeline should
//    flush at once. flush_deadline(): when pending telemetry must be written at the latest
//    (first pending record + flush_ms of wall time); nullopt when nothing is pending. Neither
//    times retries: a caller that schedules flush() (the engine) retries a failed flush with its
//    back-off (runtime/backoff.h); tick() in its own mode retries with the same Backoff, once
//    per kRetryInterval of wall time, so a full disk is not hammered.
//  * flush(bus_now) writes everything pending now and returns what it wrote and, when it failed
//    and kept the records, the store's Status (env/status.h). tick(bus_now) still flushes when urgent() or the deadline has passed, so a caller
//    that only ticks keeps working.
//  * Errors never escape: a failed write keeps the records in memory and retries. Memory for
//    retries is bounded (kRetryMemoryBytes): past it, telemetry is dropped first (oldest
//    first), then pack snapshots, lock events and ride checkpoints; command results, faults,
//    commands and the rest are only dropped past 4x the bound. Every dropped record is counted
//    (health().dropped_records). On a full disk the records that are never evicted are written
//    without the telemetry, so they do not wait behind it. Repeated identical errors are
//    logged once per 10 s with a count; recovery (space back) is automatic and logged.
//  * Opening restores an open ride of a previous run (DomainTrackers::restore) and the last
//    known BMS serial (store meta, for the battery-swap alarm) before the first message. The
//    destructor flushes, so a clean stop loses nothing that can be written.
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>

#include "gateway/config/config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/domain_trackers.h"
#include "gateway/runtime/backoff.h"
#include "env/env.h"
#include "env/status.h"
#include "gateway/runtime/gateway_core.h"
#include "storage/health.h"
#include "storage/rate_limited_log.h"
#include "storage/store.h"

namespace fleetgw::runtime {

domain::DomainConfig make_domain_config(const config::Config& config);
storage::StoreOptions make_store_options(const config::Config& config);

struct FlushOutcome {
  std::size_t records = 0;  // records written by this flush
  // Not ok: a write was attempted and failed, its records are kept for a retry (the store's
  // code: kFull, kIo, kOther). A batch the store refused (kInvalid) is dropped, not retried:
  // it is logged and counted in health().dropped_records, and the outcome stays ok.
  Status status;
};

class Recorder final : public MessageListener {
 public:
  static constexpr std::size_t kMaxBatchRecords = 4096;
  static constexpr std::size_t kRetryMemoryBytes = 8u << 20;
  static constexpr std::chrono::milliseconds kRetryInterval{1000};

  // `store` must outlive the recorder.
  // `env` must outlive the recorder: flush deadlines and retries run on its steady clock,
  // failing_since_us on its wall clock (env/env.h).
  Recorder(const config::Config& config, storage::Store& store, Micros now,
           Env& env = Env::system());
  ~Recorder() override;

  void on_message(const motinova::DecodedMessage& message, Micros now) override;
  void tick(Micros now) override;
  FlushOutcome flush(Micros now);
  // Checkpoints the WAL when it is due, outside any write transaction. Kept apart from flush()
  // so the pipeline can run it after publishing: a checkpoint's fsync never delays a result.
  void checkpoint_if_due();

  bool urgent() const;
  std::optional<std::chrono::steady_clock::time_point> flush_deadline() const;
  storage::StorageHealth health() const;

  // Queues an outbox message without a table row (device info); written by the next flush,
  // which it makes urgent.
  void queue_message(storage::UplinkMessage message);
  // Queues a geofence event: a zone_events row and its fleetgw.v1.ZoneEvent payload (outbox
  // kind "zone"); urgent like every non-telemetry record.
  void record_zone_event(storage::ZoneEventRow record, storage::Bytes payload);
  // Queues an alarm raised or cleared outside the trackers (the geofence's operating area).
  void record_alarm(storage::AlarmRow record, storage::Bytes payload);
  // Called after every successful write (the uplink polls then: new records to send).
  void set_after_flush(std::function<void()> hook) { after_flush_ = std::move(hook); }
  // A caller that schedules flush() itself (the Pipeline: urgent() -> flush after the frames
  // at hand, flush_deadline() -> its timer) turns this off: tick() then only runs the trackers,
  // so records met while one burst of frames is handled go out in one transaction, not one
  // transaction per fault or lock event (a replay of the worst-case log: ~40 k commits per
  // bus-hour down to a few thousand). Default on, for callers that only tick.
  void set_flush_on_tick(bool on) { flush_on_tick_ = on; }
  // Test hook: a smaller retry-memory bound.
  void set_retry_memory_bytes(std::size_t bytes) { retry_memory_bytes_ = bytes; }

  domain::DomainTrackers& trackers() { return trackers_; }
  const domain::DomainTrackers& trackers() const { return trackers_; }
  uint64_t batches_written() const { return batches_; }
  uint64_t write_failures() const { return failures_; }
  std::size_t pending_records() const { return retry_.size() + sink_.batch().size(); }

 private:
  std::chrono::steady_clock::time_point wall() const;
  void note_pending();
  void bound_retry_memory();
  FlushOutcome write_without_evictable(Micros now);

  storage::Store& store_;
  domain::DomainSink sink_;
  domain::DomainTrackers trackers_;
  storage::Batch retry_;  // records whose write failed, retried first
  Env* env_;
  std::chrono::steady_clock::duration flush_interval_;
  std::optional<std::chrono::steady_clock::time_point> first_pending_;
  bool flush_on_tick_ = true;
  // tick()'s own mode only (flush_on_tick): when the next attempt after a failure is due.
  Backoff tick_retry_{Backoff::Options{.initial = kRetryInterval, .max = kRetryInterval}};
  std::size_t retry_memory_bytes_ = kRetryMemoryBytes;
  Micros last_now_{0};
  uint64_t batches_ = 0;
  uint64_t failures_ = 0;
  uint64_t dropped_ = 0;
  bool last_flush_failed_ = false;
  std::int64_t failing_since_us_ = 0;
  std::string last_error_;
  storage::RateLimitedLog error_log_;
  storage::RateLimitedLog drop_log_;
  std::function<void()> after_flush_;
};

}  // namespace fleetgw::runtime
