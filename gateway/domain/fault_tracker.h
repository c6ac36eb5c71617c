// FaultTracker: fault events from every fault word on the bus (MC, BMS, OBC, IOT, locks; and the
// V3.0 HMI if one talks).
//
// Contract:
//  * Clock-free: on_message(msg, now) for fault-word messages (others are ignored), tick(now).
//  * One episode per (node, bit): a "raised" event when the bit is first seen set (immediately:
//    faults are never delayed), a "cleared" event once it has stayed clear for `debounce`. A
//    re-raise within the debounce window continues the episode and increments its occurrence
//    count instead of producing a new pair; the cleared event carries the final count.
//  * A fault word not heard for `stale` makes each of its active faults "unknown" (a distinct
//    event kind: §3.7, a silent node is not a healthy one). When the word is heard again, faults
//    still set continue their episode without a new "raised"; those now clear are cleared (after
//    the debounce window); new bits are raised.
//  * Events carry node number, bit index (normalised word), display code (-1 where the spec has
//    none), name and severity from motinova::find_fault() -- undefined bits are reported as
//    "undefined_bit_N", severity warning -- first/last seen and occurrences. Each event is one
//    FaultEvent row with its fleetgw.v1.FaultEvent payload.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <utility>

#include "gateway/domain/domain_config.h"
#include "gateway/domain/domain_sink.h"
#include "motinova/codec.h"
#include "motinova/faults.h"

namespace fleetgw::domain {

class FaultTracker {
 public:
  FaultTracker(FaultConfig config, DomainSink& sink);

  void on_message(const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);

  // Episodes raised since construction (the ride tracker counts the ones during a ride).
  uint64_t raised_total() const { return raised_total_; }
  // Number of faults currently active (raised, not cleared) on `node`, including unknown ones.
  std::size_t active(motinova::Node node) const;

 private:
  enum class Phase : uint8_t { kActive, kClearing, kUnknown };
  struct Episode {
    motinova::FaultSource source;
    Phase phase = Phase::kActive;
    Micros first_seen{0};
    Micros last_seen{0};
    Micros cleared_at{0};
    int64_t occurrences = 1;
  };
  struct Word {
    motinova::FaultSource source;
    Micros heard{0};
    bool stale = false;
  };
  using Key = std::pair<int, int>;  // node number, bit index

  void on_word(motinova::Node node, motinova::FaultSource source, uint32_t word, Micros now);
  void expire_clears(Micros now);
  void emit(const Key& key, const Episode& e, storage::FaultEventKind kind);

  FaultConfig config_;
  DomainSink& sink_;
  std::array<std::optional<Word>, 16> words_{};
  std::map<Key, Episode> episodes_;
  uint64_t raised_total_ = 0;
};

}  // namespace fleetgw::domain
