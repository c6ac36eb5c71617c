#include "gateway/campaign/campaign_spec.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "fleetgw/v1/campaign.pb.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::campaign {
namespace {

std::string spec_quoted(std::string_view received) {
  return "'" + common::untrusted_excerpt(received, 80) + "'";
}

// The window fields of one condition; nullopt-like empty string when fine.
std::string check_condition(const v1::CampaignCondition& c,
                            const motinova::SignalCatalogue& catalogue, Condition& out) {
  switch (c.kind()) {
    case v1::CAMPAIGN_CONDITION_KIND_ABOVE:
      out.kind = ConditionKind::kAbove;
      break;
    case v1::CAMPAIGN_CONDITION_KIND_BELOW:
      out.kind = ConditionKind::kBelow;
      break;
    case v1::CAMPAIGN_CONDITION_KIND_RISING_EDGE:
      out.kind = ConditionKind::kRising;
      break;
    case v1::CAMPAIGN_CONDITION_KIND_FALLING_EDGE:
      out.kind = ConditionKind::kFalling;
      break;
    case v1::CAMPAIGN_CONDITION_KIND_FAULT_ACTIVE:
      out.kind = ConditionKind::kFaultActive;
      break;
    default:
      return "trigger.condition.kind: unspecified or unknown condition";
  }
  out.signal = catalogue.find(c.signal());
  if (out.signal == nullptr) {
    return "trigger.condition.signal: unknown signal " + spec_quoted(c.signal()) +
           " (fleetgw signals lists them)";
  }
  if (!motinova::is_numeric(out.signal->type)) {
    return "trigger.condition.signal: " + out.signal->name + " is " +
           std::string(motinova::signal_type_name(out.signal->type)) + ", not numeric";
  }
  if (out.kind == ConditionKind::kFaultActive && out.signal->fault_mask == 0) {
    return "trigger.condition.signal: " + out.signal->name +
           " is not a fault or alarm bit (fault_active needs one, e.g. "
           "bms.faults.charge_over_heat_alarm)";
  }
  if (out.is_event() && c.hysteresis_e6() != 0) {
    return "trigger.condition.hysteresis_e6: only above and below conditions have one";
  }
  out.threshold =
      out.kind == ConditionKind::kFaultActive ? 0.5 : static_cast<double>(c.threshold_e6()) / 1e6;
  out.hysteresis = static_cast<double>(c.hysteresis_e6()) / 1e6;
  return {};
}

std::string check_sampling(const v1::CampaignSampling& s, CompiledCampaign& out) {
  switch (s.kind()) {
    case v1::CAMPAIGN_SAMPLING_KIND_EVERY:
      out.sampling = SamplingKind::kEvery;
      break;
    case v1::CAMPAIGN_SAMPLING_KIND_ON_CHANGE:
      out.sampling = SamplingKind::kOnChange;
      break;
    case v1::CAMPAIGN_SAMPLING_KIND_WINDOW:
      out.sampling = SamplingKind::kWindow;
      break;
    default:
      return "sampling.kind: unspecified or unknown sampling";
  }
  if (s.period_ms() < kMinPeriodMs || s.period_ms() > kMaxPeriodMs) {
    return fmt::format(
        "sampling.period_ms: {} is outside {}..{} (the bound on the campaign's rate)",
        s.period_ms(), kMinPeriodMs, kMaxPeriodMs);
  }
  out.period = Micros{std::int64_t{s.period_ms()} * 1000};
  const bool window = out.sampling == SamplingKind::kWindow;
  if (!window && (s.before_ms() != 0 || s.after_ms() != 0)) {
    return "sampling.before_ms: only window sampling has a window";
  }
  if (window) {
    if (out.trigger != TriggerKind::kCondition) {
      return "sampling.kind: window sampling needs a condition trigger (its event)";
    }
    if (s.before_ms() > kMaxWindowMs) {
      return fmt::format("sampling.before_ms: {} is over {}", s.before_ms(), kMaxWindowMs);
    }
    if (s.after_ms() > kMaxWindowMs) {
      return fmt::format("sampling.after_ms: {} is over {}", s.after_ms(), kMaxWindowMs);
    }
    if (s.before_ms() == 0 && s.after_ms() == 0) {
      return "sampling.before_ms: a window needs before_ms or after_ms";
    }
    out.before = Micros{std::int64_t{s.before_ms()} * 1000};
    out.after = Micros{std::int64_t{s.after_ms()} * 1000};
  } else if (out.trigger == TriggerKind::kCondition && out.condition.is_event()) {
    return "sampling.kind: an edge or fault condition is an instant: it needs window sampling";
  }
  return {};
}

std::string check_target(const v1::CampaignTarget& t, CompiledCampaign& out) {
  if (t.vehicle_ids().empty() && t.groups().empty() && !t.all_vehicles()) {
    return "target: no scope (vehicle_ids, groups or all_vehicles)";
  }
  for (int i = 0; i < t.vehicle_ids_size(); ++i) {
    if (!command::is_valid_tool_id(t.vehicle_ids(i))) {
      return fmt::format("target.vehicle_ids[{}]: {} is not a vehicle id", i,
                         spec_quoted(t.vehicle_ids(i)));
    }
    out.vehicle_ids.push_back(t.vehicle_ids(i));
  }
  for (int i = 0; i < t.groups_size(); ++i) {
    if (!command::is_valid_tool_id(t.groups(i))) {
      return fmt::format("target.groups[{}]: {} is not a group name", i, spec_quoted(t.groups(i)));
    }
    out.groups.push_back(t.groups(i));
  }
  out.all_vehicles = t.all_vehicles();
  if (t.firmware_size() > 8) return "target.firmware: more than 8 conditions";
  for (int i = 0; i < t.firmware_size(); ++i) {
    const auto& f = t.firmware(i);
    const auto node = motinova::node_from_name(f.node());
    if (!node || *node == motinova::Node::kBroadcast) {
      return fmt::format("target.firmware[{}].node: {} is not a node (mc, bms, obc, iot, lock1..)",
                         i, spec_quoted(f.node()));
    }
    if (f.versions().empty() && f.prefix().empty()) {
      return fmt::format("target.firmware[{}]: neither versions nor prefix", i);
    }
    if (f.versions_size() > 16) return fmt::format("target.firmware[{}].versions: over 16", i);
    FirmwareRule rule{.node = *node, .versions = {}, .prefix = f.prefix()};
    for (const auto& v : f.versions()) rule.versions.push_back(v);
    out.firmware.push_back(std::move(rule));
  }
  return {};
}

}  // namespace

std::uint64_t sample_bytes_bound(const motinova::Signal& signal) {
  // Record tag + length (3), signal index (2), offset (1 + 10), value (9) or text, invalid (2).
  constexpr std::uint64_t kFixed = 3 + 2 + 11 + 9 + 2;
  switch (signal.type) {
    case motinova::SignalType::kText:
      return kFixed + 3 + signal.field->size;
    case motinova::SignalType::kBytes:
      return kFixed + 3 + 2ull * signal.field->size;
    default:
      return kFixed;
  }
}

std::variant<CompiledCampaign, std::string> compile_campaign(
    const v1::Campaign& c, const motinova::SignalCatalogue& catalogue) {
  CompiledCampaign out;
  if (!command::is_valid_tool_id(c.id())) {
    return "id: " + spec_quoted(c.id()) + " must be 1..64 characters of [A-Za-z0-9._-]";
  }
  out.id = c.id();
  if (c.version() == 0) return std::string("version: must be at least 1");
  out.version = c.version();
  if (c.issued_at_us() <= 0) return std::string("issued_at_us: missing");
  if (c.description().size() > 256) return std::string("description: over 256 bytes");
  if (c.signals().empty()) return std::string("signals: none (a campaign collects something)");
  if (static_cast<std::size_t>(c.signals_size()) > kMaxSignals) {
    return fmt::format("signals: {} signals, at most {}", c.signals_size(), kMaxSignals);
  }
  std::set<const motinova::Signal*> seen;
  for (int i = 0; i < c.signals_size(); ++i) {
    const motinova::Signal* s = catalogue.find(c.signals(i));
    if (s == nullptr) {
      return fmt::format("signals[{}]: unknown signal {} (fleetgw signals lists them)", i,
                         spec_quoted(c.signals(i)));
    }
    if (!seen.insert(s).second) return fmt::format("signals[{}]: {} repeated", i, s->name);
    out.signals.push_back(s);
  }
  switch (c.trigger().kind()) {
    case v1::CAMPAIGN_TRIGGER_KIND_ALWAYS:
      out.trigger = TriggerKind::kAlways;
      break;
    case v1::CAMPAIGN_TRIGGER_KIND_TIME_WINDOW:
      out.trigger = TriggerKind::kTimeWindow;
      if (c.trigger().day_start_s() > 86'400 || c.trigger().day_end_s() > 86'400) {
        return std::string("trigger.day_start_s: day_start_s and day_end_s must be 0..86400");
      }
      if (c.trigger().day_start_s() == c.trigger().day_end_s()) {
        return std::string("trigger.day_end_s: an empty window (equal to day_start_s)");
      }
      out.day_start_s = c.trigger().day_start_s();
      out.day_end_s = c.trigger().day_end_s();
      break;
    case v1::CAMPAIGN_TRIGGER_KIND_CONDITION:
      out.trigger = TriggerKind::kCondition;
      if (auto e = check_condition(c.trigger().condition(), catalogue, out.condition); !e.empty()) {
        return e;
      }
      break;
    case v1::CAMPAIGN_TRIGGER_KIND_ZONE: {
      out.trigger = TriggerKind::kZone;
      const std::string& z = c.trigger().zone();
      if (z.empty() || z.size() > kMaxZoneNameBytes ||
          !std::all_of(z.begin(), z.end(), [](char ch) { return ch >= 0x20 && ch < 0x7f; })) {
        return fmt::format("trigger.zone: {} is not 1..{} printable ASCII bytes", spec_quoted(z),
                           kMaxZoneNameBytes);
      }
      out.zone = z;
      break;
    }
    default:
      return std::string("trigger.kind: unspecified or unknown trigger");
  }
  if (auto e = check_sampling(c.sampling(), out); !e.empty()) return e;
  if (c.priority() > static_cast<std::uint32_t>(kMaxPriority)) {
    return fmt::format("priority: {} is over {}", c.priority(), kMaxPriority);
  }
  out.priority = static_cast<int>(c.priority());
  if (c.disk_budget_bytes() < kMinDiskBudget || c.disk_budget_bytes() > kMaxDiskBudget) {
    return fmt::format("disk_budget_bytes: {} is outside {}..{}", c.disk_budget_bytes(),
                       kMinDiskBudget, kMaxDiskBudget);
  }
  out.disk_budget_bytes = c.disk_budget_bytes();
  if (c.start_us() <= 0 || c.end_us() <= c.start_us()) {
    return std::string("end_us: the campaign needs 0 < start_us < end_us");
  }
  if (c.end_us() - c.start_us() > kMaxDuration.count()) {
    return std::string("end_us: more than 90 days after start_us");
  }
  out.start = Micros{c.start_us()};
  out.end = Micros{c.end_us()};
  if (auto e = check_target(c.target(), out); !e.empty()) return e;

  // The cost, from the bounds just checked.
  const std::uint64_t per_hour = 3'600'000'000ull / static_cast<std::uint64_t>(out.period.count());
  for (const auto* s : out.signals) {
    out.cost.max_samples_per_hour += per_hour;
    out.cost.max_bytes_per_hour += per_hour * sample_bytes_bound(*s);
  }
  if (out.sampling == SamplingKind::kWindow) {
    const auto per_signal = static_cast<std::uint64_t>(out.before / out.period) + 1;
    out.cost.ring_samples = per_signal * out.signals.size();
    if (out.cost.ring_samples > kMaxRingSamples) {
      return fmt::format(
          "sampling.before_ms: the ring would hold {} samples ({} signals x {}), at most {}",
          out.cost.ring_samples, out.signals.size(), per_signal, kMaxRingSamples);
    }
    out.cost.ring_bytes = out.cost.ring_samples * 24;  // RingSample: time, value, flags
  }
  out.cost.disk_budget_bytes = out.disk_budget_bytes;
  return out;
}

std::string_view trigger_name(TriggerKind kind) {
  switch (kind) {
    case TriggerKind::kAlways:
      return "always";
    case TriggerKind::kTimeWindow:
      return "time_window";
    case TriggerKind::kCondition:
      return "condition";
    case TriggerKind::kZone:
      return "zone";
  }
  return "always";
}

std::string_view condition_name(ConditionKind kind) {
  switch (kind) {
    case ConditionKind::kAbove:
      return "above";
    case ConditionKind::kBelow:
      return "below";
    case ConditionKind::kRising:
      return "rising_edge";
    case ConditionKind::kFalling:
      return "falling_edge";
    case ConditionKind::kFaultActive:
      return "fault_active";
  }
  return "above";
}

std::string_view sampling_name(SamplingKind kind) {
  switch (kind) {
    case SamplingKind::kEvery:
      return "every";
    case SamplingKind::kOnChange:
      return "on_change";
    case SamplingKind::kWindow:
      return "window";
  }
  return "every";
}

}  // namespace fleetgw::campaign
