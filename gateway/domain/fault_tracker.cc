#include "gateway/domain/fault_tracker.h"

#include <bit>
#include <string>
#include <utility>

#include "gateway/domain/payloads.h"
#include "motinova/can.h"
#include "motinova/fault_names.h"

namespace fleetgw::domain {

FaultTracker::FaultTracker(FaultConfig config, DomainSink& sink)
    : config_(std::move(config)), sink_(sink) {}

void FaultTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr ||
      msg.desc->kind != motinova::MessageKind::kFaultWord) {
    return;
  }
  const auto raw = msg.raw("raw");
  if (!raw) return;
  // Clears whose window ended before this word are settled first, so that a re-raise after the
  // window is a new episode even when no tick() ran in between.
  expire_clears(now);
  on_word(msg.desc->source(), msg.desc->fault_source, static_cast<uint32_t>(*raw), now);
}

void FaultTracker::on_word(motinova::Node node, motinova::FaultSource source, uint32_t word,
                           Micros now) {
  const int n = static_cast<int>(node);
  words_[static_cast<std::size_t>(n) & 0xF] = Word{source, now, false};

  for (unsigned bit = 0; bit < 32; ++bit) {
    const bool set = (word >> bit) & 1u;
    const Key key{n, static_cast<int>(bit)};
    const auto it = episodes_.find(key);
    if (set) {
      if (it == episodes_.end()) {
        Episode e{.source = source, .first_seen = now, .last_seen = now};
        emit(key, e, storage::FaultEventKind::kRaised);
        episodes_.emplace(key, e);
        ++raised_total_;
        continue;
      }
      Episode& e = it->second;
      if (e.phase == Phase::kClearing) ++e.occurrences;  // flapping: same episode
      e.phase = Phase::kActive;  // from kUnknown: still set, not raised again
      e.last_seen = now;
    } else if (it != episodes_.end() && it->second.phase != Phase::kClearing) {
      it->second.phase = Phase::kClearing;
      it->second.cleared_at = now;
    }
  }
}

void FaultTracker::expire_clears(Micros now) {
  for (auto it = episodes_.begin(); it != episodes_.end();) {
    if (it->second.phase == Phase::kClearing && now - it->second.cleared_at >= config_.debounce) {
      emit(it->first, it->second, storage::FaultEventKind::kCleared);
      it = episodes_.erase(it);
    } else {
      ++it;
    }
  }
}

void FaultTracker::tick(Micros now) {
  expire_clears(now);
  for (std::size_t n = 0; n < words_.size(); ++n) {
    std::optional<Word>& w = words_[n];
    if (!w || w->stale || now - w->heard <= config_.stale) continue;
    w->stale = true;
    for (auto& [key, e] : episodes_) {
      if (key.first != static_cast<int>(n) || e.phase != Phase::kActive) continue;
      e.phase = Phase::kUnknown;
      emit(key, e, storage::FaultEventKind::kUnknown);
    }
  }
}

std::size_t FaultTracker::active(motinova::Node node) const {
  std::size_t count = 0;
  for (const auto& [key, e] : episodes_) {
    if (key.first == static_cast<int>(node) && e.phase != Phase::kClearing) ++count;
  }
  return count;
}

void FaultTracker::emit(const Key& key, const Episode& e, storage::FaultEventKind kind) {
  const uint32_t mask = uint32_t{1} << key.second;
  const std::optional<motinova::FaultDef> found =
      motinova::describe_fault(e.source, mask, config_.fault_names);
  const motinova::FaultDef* def = found ? &*found : nullptr;
  storage::FaultEventRow ev;
  ev.node = key.first;
  ev.bit = key.second;
  ev.code = def ? def->code : -1;
  ev.name = def ? std::string(def->name) : "undefined_bit_" + std::to_string(key.second);
  ev.severity =
      std::string(motinova::severity_name(def ? def->severity : motinova::Severity::kWarning));
  ev.event = kind;
  ev.first_seen_us = e.first_seen.count();
  ev.last_seen_us = e.last_seen.count();
  ev.occurrences = e.occurrences;
  const auto node_name = motinova::node_name(static_cast<motinova::Node>(key.first));
  storage::Bytes payload = fault_payload(ev, node_name);
  sink_.batch().faults.push_back({std::move(ev), std::move(payload)});
}

}  // namespace fleetgw::domain
