// A campaign (fleetgw.v1.Campaign) checked against the gateway's rules and the signal catalogue
// and compiled into what the engine runs -- or refused with a reason naming the field. Pure: no
// clock, no I/O. docs/campaigns.md states every rule and bound.
//
// Contract:
//  * compile_campaign() refuses, naming the field ("signals[2]", "trigger.condition.signal",
//    "sampling.period_ms"...): an id that is not 1..64 of [A-Za-z0-9._-]; version 0; no
//    issued_at; no signal, more than kMaxSignals, an unknown or repeated one; an unspecified or
//    unknown trigger or sampling kind; a day window outside 0..86400 s or empty; a zone trigger
//    without a zone or with one over 64 bytes or not printable ASCII; a condition on
//    an unknown or non-numeric signal, FAULT_ACTIVE on a signal that is not a fault bit, a
//    hysteresis on an edge or fault condition; window sampling without a condition, an
//    edge or fault condition without window sampling; a period under kMinPeriodMs or over an
//    hour; a window side over kMaxWindowMs, a ring over kMaxRingSamples entries in all; a
//    priority over 9; a disk budget outside [kMinDiskBudget, kMaxDiskBudget]; start/end not
//    0 < start < end or more than kMaxDuration apart; no target scope, an invalid vehicle id
//    or group, a firmware condition on an unknown node or with nothing to match; a
//    description over 256 bytes.
//  * Cost bounded by construction: every signal is sampled at most once per period_ms, so a
//    campaign produces at most max_samples_per_hour samples an hour and at most
//    max_bytes_per_hour bytes of payload (each sample's encoded size bounded per signal type);
//    its ring holds at most ring_samples entries (ring_bytes of memory); its results hold at
//    most disk_budget_bytes of the store; its CPU per decoded message is one look-up plus
//    O(its signals in that message).
#pragma once

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "motinova/can.h"
#include "motinova/signal_catalogue.h"

namespace fleetgw::v1 {
class Campaign;
}  // namespace fleetgw::v1

namespace fleetgw::campaign {

using motinova::Micros;

inline constexpr std::size_t kMaxSignals = 64;
// 0 (most urgent) .. kMaxPriority among campaigns: the outbox queues them at 6..15, below every
// record of the product (storage::OutboxPriority::kCampaign).
inline constexpr int kMaxPriority = 9;
inline constexpr std::uint32_t kMinPeriodMs = 10;
inline constexpr std::uint32_t kMaxPeriodMs = 3'600'000;
inline constexpr std::uint32_t kMaxWindowMs = 600'000;
inline constexpr std::size_t kMaxRingSamples = 65'536;
inline constexpr std::uint64_t kMinDiskBudget = 4096;
inline constexpr std::uint64_t kMaxDiskBudget = 64ull << 20;
inline constexpr Micros kMaxDuration{90ll * 86'400'000'000};

enum class TriggerKind : std::uint8_t { kAlways, kTimeWindow, kCondition, kZone };
inline constexpr std::size_t kMaxZoneNameBytes = 64;
enum class ConditionKind : std::uint8_t { kAbove, kBelow, kRising, kFalling, kFaultActive };
enum class SamplingKind : std::uint8_t { kEvery, kOnChange, kWindow };

struct Condition {
  ConditionKind kind = ConditionKind::kAbove;
  const motinova::Signal* signal = nullptr;
  double threshold = 0;
  double hysteresis = 0;
  bool is_event() const { return kind != ConditionKind::kAbove && kind != ConditionKind::kBelow; }
};

struct FirmwareRule {
  motinova::Node node = motinova::Node::kMc;
  std::vector<std::string> versions;
  std::string prefix;
};

struct CampaignCost {
  std::uint64_t max_samples_per_hour = 0;
  std::uint64_t max_bytes_per_hour = 0;
  std::uint64_t ring_samples = 0;
  std::uint64_t ring_bytes = 0;
  std::uint64_t disk_budget_bytes = 0;
};

struct CompiledCampaign {
  std::string id;
  std::uint64_t version = 0;
  std::vector<const motinova::Signal*> signals;
  TriggerKind trigger = TriggerKind::kAlways;
  std::uint32_t day_start_s = 0, day_end_s = 0;
  Condition condition;
  std::string zone;  // kZone: a zone's id or name
  SamplingKind sampling = SamplingKind::kEvery;
  Micros period{0}, before{0}, after{0};
  int priority = 0;
  std::uint64_t disk_budget_bytes = 0;
  Micros start{0}, end{0};
  std::vector<std::string> vehicle_ids, groups;
  bool all_vehicles = false;
  std::vector<FirmwareRule> firmware;
  CampaignCost cost;
};

// Upper bound of one encoded CampaignSample of `signal` (tags, index, offset, value or text).
std::uint64_t sample_bytes_bound(const motinova::Signal& signal);

std::variant<CompiledCampaign, std::string> compile_campaign(
    const v1::Campaign& campaign,
    const motinova::SignalCatalogue& catalogue = motinova::SignalCatalogue::standard());

// "always", "time_window", "condition", "zone"; "above", "below", "rising_edge", "falling_edge",
// "fault_active"; "every", "on_change", "window" (the file syntax, campaign_file.h).
std::string_view trigger_name(TriggerKind kind);
std::string_view condition_name(ConditionKind kind);
std::string_view sampling_name(SamplingKind kind);

}  // namespace fleetgw::campaign
