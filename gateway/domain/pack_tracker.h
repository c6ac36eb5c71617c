// PackTracker: battery-pack snapshots (storage::PackSnapshotRow + fleetgw.v1.PackStatistics).
//
// Contract:
//  * Clock-free: on_message(msg, now) (bms_status, bms_cells, bms_temps, pack_stats, BMS model
//    info; others ignored), tick(now).
//  * A snapshot is taken every `period` while the BMS is heard (the first `settle` after its
//    first status, so cells and temperatures are in it), and immediately whenever a lifetime
//    counter changes: a *_count field or the cycle count of pack_stats (0x725/0x5028), or the
//    cycle count of bms_status. The first pack_stats heard is a baseline, not a change.
//  * Snapshot content: BMS status (voltage, current charge-positive, SOC, SOH, cycles), cells
//    (min, max, spread, 1-based index of min and max; unpopulated cells, reported as 0 mV, are
//    ignored), temperatures [bms_status temp_c, bms_temps temp_max_c, temp_min_c] (those heard
//    within `stale`), and every pack_stats field as a JSON object (lifetime_json, "{}" when the
//    pack statistics were never read). Values older than `stale` are left out (not measured).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "gateway/domain/signals.h"
#include "motinova/codec.h"

namespace fleetgw::domain {

class PackTracker {
 public:
  PackTracker(PackConfig config, DomainSink& sink);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);

  uint64_t snapshots() const { return snapshots_; }

 private:
  void snapshot(Micros now);

  PackConfig config_;
  DomainSink& sink_;
  std::optional<Reading> voltage_, current_, soc_, soh_, cycles_, remaining_, full_, temp_;
  std::optional<Reading> temp_max_, temp_min_;
  std::vector<int> cells_mv_;
  Micros cells_at_{0};
  nlohmann::json lifetime_ = nlohmann::json::object();
  std::optional<nlohmann::json> counters_;  // the counters of the last pack_stats
  std::string serial_;
  std::optional<Micros> next_due_;
  uint64_t snapshots_ = 0;
};

}  // namespace fleetgw::domain
