// Storage health as the service reports it in `fleetgw status` and the published Status.
#pragma once

#include <cstdint>
#include <string>

namespace fleetgw::storage {

struct StorageHealth {
  bool failing = false;    // the most recent write attempt failed
  std::string last_error;  // reason of the most recent failure, e.g. "disk full (SQLITE_FULL)"
  std::uint64_t failed_writes = 0;  // failed write attempts since start
  std::int64_t failing_since_us =
      0;  // wall clock (us since epoch) when the current failing stretch began; 0 when not failing
  std::uint64_t configured_budget_bytes = 0;  // storage.max_mb as configured (0 = unlimited)
  std::uint64_t effective_budget_bytes =
      0;                              // smaller than configured when clamped to the disk's size
  std::uint64_t dropped_records = 0;  // records given up because retry memory is bounded
  // Added by H-storage after the contract's fields:
  std::uint64_t full_recoveries =
      0;  // writes that hit SQLITE_FULL and succeeded after evicting telemetry
  std::uint64_t pending_records =
      0;  // records held in memory waiting for a (re)try (Recorder::health)
};

// What the store's background WAL checkpointer did since open (storage/checkpointer.h).
struct CheckpointCounters {
  std::uint64_t requested = 0;  // checkpoint requests (coalesced while one is pending)
  std::uint64_t completed = 0;  // checkpoints that copied every WAL frame
  std::uint64_t partial = 0;    // checkpoints a reader (or a concurrent checkpoint) cut short
  std::uint64_t failed = 0;     // SQLite errors (logged, rate-limited)
};

}  // namespace fleetgw::storage
