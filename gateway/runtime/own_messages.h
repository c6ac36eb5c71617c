// OwnMessages: the messages the gateway's own node transmits, each kept with its decoded form,
// so that showing them to the listeners (GatewayCore's echoes) costs a lookup, not a decode.
//
// Why: the bus does not echo a sender's own frames, yet the trackers need the gateway's
// LOCK/UNLOCK/SHUTDOWN broadcasts. The node transmits few distinct messages (its poll
// requests, keyword broadcasts, lock commands, model info, a fault word), again and again, so
// each distinct one is decoded the first time it is sent and never again: every further
// transmission hands the listeners the DecodedMessage kept from that first time. The frame is
// encoded once, for the bus (node::TransportSender); nothing is decoded per transmission.
//
// Contract:
//  * intern(frame) returns the entry equal to `frame` (same ID, mode, function and data),
//    decoding it only when no such entry exists (decodes() counts those). The DecodedMessage
//    is exactly what motinova::decode gives for the frame with these options.
//  * Entries stay valid (their address is stable) until trim(); trim() forgets everything once
//    more than kCapacity distinct messages were seen, which bounds the memory (about 3 KB an
//    entry) should a node ever send many distinct values. The caller trims only when it holds
//    no entry (GatewayCore: no echo pending).
//  * `catalogue` and `options` must outlive the table (the decoded views point into them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <unordered_map>

#include "motinova/codec.h"

namespace fleetgw::runtime {

class OwnMessages {
 public:
  static constexpr std::size_t kCapacity = 48;

  struct Entry {
    motinova::AppFrame frame;
    motinova::DecodedMessage decoded;  // views into `frame`
  };

  OwnMessages(const motinova::Catalogue& catalogue, const motinova::DecodeOptions& options)
      : catalogue_(catalogue), options_(options) {}
  OwnMessages(const OwnMessages&) = delete;
  OwnMessages& operator=(const OwnMessages&) = delete;

  const Entry& intern(const motinova::AppFrame& frame);
  void trim();

  std::size_t size() const { return entries_.size(); }
  std::uint64_t decodes() const { return decodes_; }

 private:
  const motinova::Catalogue& catalogue_;
  const motinova::DecodeOptions& options_;
  std::deque<Entry> entries_;  // a deque: growing never moves an entry
  std::unordered_multimap<std::uint64_t, const Entry*> by_hash_;
  std::uint64_t decodes_ = 0;
};

}  // namespace fleetgw::runtime
