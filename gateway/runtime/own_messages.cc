#include "gateway/runtime/own_messages.h"

namespace fleetgw::runtime {
namespace {

// FNV-1a over what makes two frames the same message.
std::uint64_t hash_of(const motinova::AppFrame& f) {
  std::uint64_t h = 14695981039346656037ull;
  const auto mix = [&h](std::uint8_t b) {
    h ^= b;
    h *= 1099511628211ull;
  };
  mix(static_cast<std::uint8_t>(f.can_id >> 8));
  mix(static_cast<std::uint8_t>(f.can_id));
  mix(static_cast<std::uint8_t>(f.mode));
  mix(f.function);
  mix(static_cast<std::uint8_t>(f.data.size()));
  for (const std::uint8_t b : f.data) mix(b);
  return h;
}

}  // namespace

const OwnMessages::Entry& OwnMessages::intern(const motinova::AppFrame& frame) {
  const std::uint64_t h = hash_of(frame);
  const auto [first, last] = by_hash_.equal_range(h);
  for (auto it = first; it != last; ++it) {
    if (it->second->frame == frame) return *it->second;
  }
  Entry& e = entries_.emplace_back();
  e.frame = frame;
  motinova::decode(e.frame, catalogue_, options_, e.decoded);
  ++decodes_;
  by_hash_.emplace(h, &e);
  return e;
}

void OwnMessages::trim() {
  if (entries_.size() <= kCapacity) return;
  by_hash_.clear();
  entries_.clear();
}

}  // namespace fleetgw::runtime
