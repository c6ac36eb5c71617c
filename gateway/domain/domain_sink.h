// DomainSink: where the trackers put what they produce, until the gateway writes it to the
// Store (every ~200 ms, one transaction).
//
// Contract: owned by the caller and passed by reference to the trackers, which only append to
// batch(); it must outlive them. take() hands the accumulated records over (with now_us set) and
// leaves the sink empty, so a flush can be `store.write(sink.take(now))` (the service's recorder
// instead moves batch()'s records out itself, keeping the vectors' capacity). Records appear in
// the order the trackers produced them; a ride's checkpoint and its close may share one batch
// (the store upserts by ride_id, so the last one wins).
#pragma once

#include <utility>

#include "motinova/can.h"
#include "storage/store.h"

namespace fleetgw::domain {

class DomainSink {
 public:
  storage::Batch& batch() { return batch_; }
  const storage::Batch& batch() const { return batch_; }
  bool empty() const { return batch_.empty(); }

  storage::Batch take(motinova::Micros now) {
    storage::Batch out = std::exchange(batch_, storage::Batch{});
    out.now_us = now.count();
    return out;
  }

 private:
  storage::Batch batch_;
};

}  // namespace fleetgw::domain
