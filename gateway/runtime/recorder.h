// Recorder: the storage stage of the pipeline. It feeds every decoded message to the domain
// trackers and writes what they produce to the SQLite store in one transaction per flush
// interval (default 200 ms), so the bus never waits for the disk more than once per interval.
//
// Contract:
//  * Single-threaded, clock-free (it is a MessageListener: on_message/tick with `now`).
//  * Opening restores an open ride of a previous run (DomainTrackers::restore) before the first
//    message. flush() writes whatever is pending; the destructor flushes too, so a clean stop
//    loses nothing. A crash loses at most the last interval (never the database).
//  * A failed write (disk error) is logged and the batch is kept for the next flush: records
//    are never dropped silently.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>

#include "gateway/config/config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/domain_trackers.h"
#include "gateway/runtime/gateway_core.h"
#include "storage/health.h"
#include "storage/store.h"

namespace fleetgw::runtime {

struct FlushOutcome {
  std::size_t records = 0;
  bool failed = false;
};

domain::DomainConfig make_domain_config(const config::Config& config);
storage::StoreOptions make_store_options(const config::Config& config);

class Recorder final : public MessageListener {
 public:
  using WallClock = std::function<std::chrono::steady_clock::time_point()>;
  // `store` must outlive the recorder.
  Recorder(const config::Config& config, storage::Store& store, Micros now,
           WallClock wall_clock = {});
  ~Recorder() override;

  void on_message(const motinova::DecodedMessage& message, Micros now) override;
  // Trackers' tick; flushes when urgent() or the wall-clock flush deadline has passed.
  void tick(Micros now) override;
  FlushOutcome flush(Micros now);

  // A pending record is not telemetry (results, faults, rides, locks...) or the pending batch
  // reached its size limit: the pipeline flushes at once.
  bool urgent() const;
  // When pending telemetry must be written at the latest (wall clock); nullopt: nothing pending.
  std::optional<std::chrono::steady_clock::time_point> flush_deadline() const;
  storage::StorageHealth health() const;

  // Called after every successful write (the uplink polls then: new records to send).
  void set_after_flush(std::function<void()> hook) { after_flush_ = std::move(hook); }

  domain::DomainTrackers& trackers() { return trackers_; }
  uint64_t batches_written() const { return batches_; }
  uint64_t write_failures() const { return failures_; }

 private:
  storage::Store& store_;
  domain::DomainSink sink_;
  domain::DomainTrackers trackers_;
  void note_pending();

  storage::Batch pending_;  // a batch whose write failed, retried first
  std::chrono::steady_clock::duration flush_interval_;
  WallClock wall_clock_;
  std::optional<std::chrono::steady_clock::time_point> pending_since_;
  Micros last_now_{0};
  uint64_t batches_ = 0;
  uint64_t failures_ = 0;
  std::function<void()> after_flush_;
};

}  // namespace fleetgw::runtime
