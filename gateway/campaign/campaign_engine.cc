#include "gateway/campaign/campaign_engine.h"

#include <algorithm>
#include <cmath>

#include "fleetgw/v1/campaign.pb.h"

namespace fleetgw::campaign {

// Named, not anonymous: CampaignRunner (declared in the header, so of external linkage) holds
// them, and gcc's -Wsubobject-linkage refuses anonymous-namespace members there in a unity build.
namespace engine_detail {

struct Sample {
  std::uint32_t signal = 0;
  Micros t{0};
  double value = 0;
  std::string text;
  bool invalid = false;
};

struct RingSample {
  Micros t{0};
  double value = 0;
  bool invalid = false;
};

}  // namespace engine_detail
using engine_detail::RingSample;
using engine_detail::Sample;

namespace {

// Few, large records: each is a transaction of the store and a publish (the CPU figure of
// bench/campaign-cpu.sh), and campaign data is not awaited live.
constexpr std::size_t kRecordSamples = 1024;
constexpr Micros kRecordAge{30'000'000};
constexpr Micros kNever{INT64_MIN / 2};

// Values travel as integers times 10^6 (no floating point on the wire); every catalogue value
// is far inside the range (a 32-bit raw value times its scale).
std::int64_t value_e6(double value) {
  constexpr double kLimit = 9.0e18;
  const double scaled = std::round(value * 1e6);
  if (!(scaled > -kLimit)) return static_cast<std::int64_t>(-kLimit);
  if (!(scaled < kLimit)) return static_cast<std::int64_t>(kLimit);
  return static_cast<std::int64_t>(scaled);
}

bool in_day_window(Micros now, std::uint32_t start_s, std::uint32_t end_s) {
  const auto s = now.count() / 1'000'000;
  const auto tod = static_cast<std::uint32_t>(((s % 86'400) + 86'400) % 86'400);
  return start_s < end_s ? (tod >= start_s && tod < end_s) : (tod >= start_s || tod < end_s);
}

}  // namespace

std::string_view run_state_name(RunState state) {
  switch (state) {
    case RunState::kScheduled:
      return "scheduled";
    case RunState::kWaitingFirmware:
      return "waiting_firmware";
    case RunState::kNotTargeted:
      return "not_targeted";
    case RunState::kRunning:
      return "running";
    case RunState::kEnded:
      return "ended";
  }
  return "scheduled";
}

// One campaign's state: its condition, the last sample of each signal, the ring (window
// sampling) and the samples not yet cut into a record.
class CampaignRunner {
 public:
  explicit CampaignRunner(CompiledCampaign c) : c_(std::move(c)), slots_(c_.signals.size()) {
    if (c_.sampling == SamplingKind::kWindow) {
      const auto capacity = static_cast<std::size_t>(c_.before / c_.period) + 1;
      for (auto& s : slots_) s.ring.resize(capacity);
    }
  }

  const CompiledCampaign& campaign() const { return c_; }
  const CampaignCounters& counters() const { return counters_; }

  void set_firmware(const std::map<motinova::Node, std::string>& seen) {
    firmware_ok_ = true;
    firmware_known_ = true;
    for (const auto& rule : c_.firmware) {
      const auto it = seen.find(rule.node);
      if (it == seen.end()) {
        firmware_known_ = false;
        continue;
      }
      const std::string& fw = it->second;
      const bool match =
          std::find(rule.versions.begin(), rule.versions.end(), fw) != rule.versions.end() ||
          (!rule.prefix.empty() && fw.starts_with(rule.prefix));
      firmware_ok_ = firmware_ok_ && match;
    }
  }

  RunState state(Micros now) const {
    if (now >= c_.end) return RunState::kEnded;
    if (now < c_.start) return RunState::kScheduled;
    if (firmware_known_ && !firmware_ok_) return RunState::kNotTargeted;
    if (!firmware_known_) return RunState::kWaitingFirmware;
    return RunState::kRunning;
  }

  void on_condition(Micros now, const motinova::SignalValue& v) {
    if (!v.valid || state(now) != RunState::kRunning) return;
    const double x = v.number;
    const Condition& k = c_.condition;
    bool event = false;
    switch (k.kind) {
      case ConditionKind::kAbove:
        if (!active_ && x > k.threshold)
          event = active_ = true;
        else if (active_ && x < k.threshold - k.hysteresis)
          active_ = false;
        break;
      case ConditionKind::kBelow:
        if (!active_ && x < k.threshold)
          event = active_ = true;
        else if (active_ && x > k.threshold + k.hysteresis)
          active_ = false;
        break;
      case ConditionKind::kRising:
      case ConditionKind::kFaultActive:
        event = has_prev_ && prev_ <= k.threshold && x > k.threshold;
        break;
      case ConditionKind::kFalling:
        event = has_prev_ && prev_ >= k.threshold && x < k.threshold;
        break;
    }
    has_prev_ = true;
    prev_ = x;
    if (!event) return;
    ++counters_.events;
    if (c_.sampling != SamplingKind::kWindow) return;
    trigger_at_ = now;
    if (now > after_until_) {
      // A new window: the ring's samples of [now - before, now], in time order.
      for (std::size_t i = 0; i < slots_.size(); ++i)
        drain_ring(static_cast<std::uint32_t>(i), now);
      std::stable_sort(pending_.begin(), pending_.end(),
                       [](const Sample& a, const Sample& b) { return a.t < b.t; });
    }
    after_until_ = now + c_.after;
  }

  void on_value(Micros now, std::uint32_t slot, const motinova::SignalValue& v) {
    if (state(now) != RunState::kRunning) return;
    Slot& s = slots_[slot];
    if (now - s.last_t < c_.period) return;
    const motinova::Signal& signal = *c_.signals[slot];
    switch (c_.sampling) {
      case SamplingKind::kEvery:
        if (!holds(now)) return;
        break;
      case SamplingKind::kOnChange:
        if (!holds(now)) return;
        if (s.has_last && same(signal, s, v)) return;
        break;
      case SamplingKind::kWindow:
        if (now > after_until_) {
          s.last_t = now;
          s.ring[s.ring_next] = RingSample{now, v.number, !v.valid};
          s.ring_next = (s.ring_next + 1) % s.ring.size();
          s.ring_count = std::min(s.ring_count + 1, s.ring.size());
          return;
        }
        break;
    }
    s.last_t = now;
    s.has_last = true;
    s.last_value = v.number;
    s.last_text = text_of(signal, v);
    keep(Sample{slot, now, v.number, s.last_text, !v.valid});
  }

  // Cuts a record when one is due (or `force`d); appends it to `out`.
  void cut(Micros now, bool force, std::vector<CampaignRecord>& out) {
    if (pending_.empty()) return;
    const bool in_window = c_.sampling == SamplingKind::kWindow && now <= after_until_;
    const bool due = pending_.size() >= kRecordSamples ||
                     (!in_window && (c_.sampling == SamplingKind::kWindow ||
                                     now - pending_.front().t >= kRecordAge));
    if (!force && !due) return;
    v1::CampaignSamples rec;
    rec.set_campaign_id(c_.id);
    rec.set_campaign_version(c_.version);
    for (const auto* s : c_.signals) rec.add_signals(s->name);
    const Micros base = pending_.front().t;
    rec.set_base_us(base.count());
    if (c_.sampling == SamplingKind::kWindow) rec.set_trigger_at_us(trigger_at_.count());
    rec.set_dropped(dropped_since_record_);
    for (const Sample& s : pending_) {
      auto* p = rec.add_samples();
      p->set_signal(s.signal);
      p->set_offset_us(static_cast<std::uint64_t>((s.t - base).count()));
      if (!s.text.empty())
        p->set_text(s.text);
      else
        p->set_value_e6(value_e6(s.value));
      p->set_invalid(s.invalid);
    }
    CampaignRecord r{c_.id, c_.version, c_.priority, rec.SerializeAsString(), pending_.size()};
    counters_.records += 1;
    counters_.record_bytes += r.payload.size();
    counters_.bytes_in_store += r.payload.size();
    pending_bytes_ = 0;
    dropped_since_record_ = 0;
    pending_.clear();
    out.push_back(std::move(r));
  }

  void release(std::uint64_t bytes) {
    counters_.bytes_in_store -= std::min(bytes, counters_.bytes_in_store);
  }
  void set_bytes_in_store(std::uint64_t bytes) { counters_.bytes_in_store = bytes; }
  void set_zones(const std::map<std::string, std::string, std::less<>>& inside) {
    in_zone_ = false;
    for (const auto& [id, name] : inside) {
      in_zone_ = in_zone_ || id == c_.zone || name == c_.zone;
    }
  }

 private:
  struct Slot {
    Micros last_t = kNever;
    bool has_last = false;
    double last_value = 0;
    std::string last_text;
    std::vector<RingSample> ring;
    std::size_t ring_next = 0, ring_count = 0;
  };

  bool holds(Micros now) const {
    switch (c_.trigger) {
      case TriggerKind::kAlways:
        return true;
      case TriggerKind::kTimeWindow:
        return in_day_window(now, c_.day_start_s, c_.day_end_s);
      case TriggerKind::kCondition:
        return active_;
      case TriggerKind::kZone:
        return in_zone_;
    }
    return false;
  }

  static std::string text_of(const motinova::Signal& signal, const motinova::SignalValue& v) {
    if (signal.type == motinova::SignalType::kText) return std::string(v.text);
    if (signal.type == motinova::SignalType::kBytes) return motinova::hex_text(v.bytes);
    return {};
  }

  static bool same(const motinova::Signal& signal, const Slot& s, const motinova::SignalValue& v) {
    if (!motinova::is_numeric(signal.type)) return s.last_text == text_of(signal, v);
    return s.last_value == v.number;
  }

  void drain_ring(std::uint32_t slot, Micros event) {
    Slot& s = slots_[slot];
    const std::size_t n = s.ring.size();
    for (std::size_t k = 0; k < s.ring_count; ++k) {
      const RingSample& r = s.ring[(s.ring_next + n - s.ring_count + k) % n];
      if (r.t >= event - c_.before && r.t <= event) keep(Sample{slot, r.t, r.value, {}, r.invalid});
    }
    s.ring_count = 0;
  }

  void keep(Sample sample) {
    const std::uint64_t size = sample_bytes_bound(*c_.signals[sample.signal]);
    if (counters_.bytes_in_store + pending_bytes_ + size > c_.disk_budget_bytes) {
      ++counters_.dropped;
      ++dropped_since_record_;
      return;
    }
    pending_bytes_ += size;
    ++counters_.samples;
    pending_.push_back(std::move(sample));
  }

  CompiledCampaign c_;
  std::vector<Slot> slots_;
  bool firmware_ok_ = true, firmware_known_ = true;
  bool active_ = false;   // level condition holds
  bool in_zone_ = false;  // zone trigger: the bike is inside the zone
  bool has_prev_ = false;
  double prev_ = 0;
  Micros trigger_at_{0};
  Micros after_until_ = kNever;
  std::vector<Sample> pending_;
  std::uint64_t pending_bytes_ = 0;
  std::uint64_t dropped_since_record_ = 0;
  CampaignCounters counters_;
};

CampaignEngine::CampaignEngine() = default;
CampaignEngine::~CampaignEngine() = default;

void CampaignEngine::put(CompiledCampaign campaign, Micros now) {
  remove(campaign.id, now);
  runners_.push_back(std::make_unique<CampaignRunner>(std::move(campaign)));
  runners_.back()->set_firmware(firmware_);
  runners_.back()->set_zones(zones_inside_);
  rebuild_index();
}

void CampaignEngine::remove(std::string_view id, Micros now) {
  for (auto it = runners_.begin(); it != runners_.end(); ++it) {
    if ((*it)->campaign().id != id) continue;
    (*it)->cut(now, true, records_);
    runners_.erase(it);
    rebuild_index();
    return;
  }
}

void CampaignEngine::rebuild_index() {
  index_.clear();
  for (const auto& r : runners_) {
    const CompiledCampaign& c = r->campaign();
    // The condition first: it decides the samples of the same message.
    if (c.trigger == TriggerKind::kCondition) {
      index_[c.condition.signal->message].push_back({r.get(), -1, c.condition.signal, 0});
    }
    for (std::size_t i = 0; i < c.signals.size(); ++i) {
      index_[c.signals[i]->message].push_back({r.get(), static_cast<int>(i), c.signals[i], 0});
    }
  }
  // Conditions before samples within each message, whatever the campaign order.
  for (auto& [desc, hooks] : index_) {
    std::stable_partition(hooks.begin(), hooks.end(), [](const Hook& h) { return h.slot < 0; });
  }
}

void CampaignEngine::note_firmware(const motinova::DecodedMessage& message) {
  const std::string_view fw = message.text("fw");
  auto& known = firmware_[message.desc->source()];
  if (known == fw) return;
  known = std::string(fw);
  for (const auto& r : runners_) r->set_firmware(firmware_);
}

void CampaignEngine::on_message(Micros now, const motinova::DecodedMessage& message) {
  if (message.desc == nullptr) return;
  if (message.desc->kind == motinova::MessageKind::kModelInfo && !runners_.empty()) {
    note_firmware(message);
  }
  const auto it = index_.find(message.desc);
  if (it == index_.end()) return;
  const auto values = message.values();
  for (Hook& h : it->second) {
    // A message's fields come in the same order every time: one comparison, not a search.
    if (h.value_at >= values.size() || values[h.value_at].field != h.signal->field) {
      h.value_at = values.size();
      for (std::size_t i = 0; i < values.size(); ++i) {
        if (values[i].field == h.signal->field) {
          h.value_at = i;
          break;
        }
      }
      if (h.value_at == values.size()) continue;
    }
    const auto value =
        motinova::SignalCatalogue::read(*h.signal, values[h.value_at], message.data_order);
    if (h.slot < 0) {
      h.runner->on_condition(now, value);
    } else {
      h.runner->on_value(now, static_cast<std::uint32_t>(h.slot), value);
    }
  }
  for (const auto& r : runners_) r->cut(now, false, records_);
}

void CampaignEngine::on_zone(std::string_view zone_id, std::string_view zone_name, bool inside) {
  if (inside) {
    zones_inside_.insert_or_assign(std::string(zone_id), std::string(zone_name));
  } else if (const auto it = zones_inside_.find(zone_id); it != zones_inside_.end()) {
    zones_inside_.erase(it);
  }
  for (const auto& r : runners_) {
    if (r->campaign().trigger == TriggerKind::kZone) r->set_zones(zones_inside_);
  }
}

void CampaignEngine::tick(Micros now) {
  for (const auto& r : runners_) r->cut(now, r->state(now) == RunState::kEnded, records_);
}

std::vector<CampaignRecord> CampaignEngine::take_records() {
  return std::exchange(records_, {});
}

void CampaignEngine::release(std::string_view id, std::uint64_t bytes) {
  for (const auto& r : runners_) {
    if (r->campaign().id == id) r->release(bytes);
  }
}

void CampaignEngine::set_bytes_in_store(std::string_view id, std::uint64_t bytes) {
  for (const auto& r : runners_) {
    if (r->campaign().id == id) r->set_bytes_in_store(bytes);
  }
}

void CampaignEngine::store_holds(std::uint64_t bytes) {
  scale_to(bytes, [](const CampaignRunner&) { return true; });
}

void CampaignEngine::store_holds_at(int priority, std::uint64_t bytes) {
  scale_to(bytes,
           [priority](const CampaignRunner& r) { return r.campaign().priority == priority; });
}

template <typename Pred>
void CampaignEngine::scale_to(std::uint64_t bytes, Pred pred) {
  std::uint64_t counted = 0;
  for (const auto& r : runners_) {
    if (pred(*r)) counted += r->counters().bytes_in_store;
  }
  if (counted <= bytes) return;
  for (const auto& r : runners_) {
    if (!pred(*r)) continue;
    const std::uint64_t mine = r->counters().bytes_in_store;
    const auto keep = static_cast<std::uint64_t>(static_cast<long double>(mine) * bytes / counted);
    r->release(mine - keep);
  }
}

std::vector<CampaignEngine::View> CampaignEngine::view(Micros now) const {
  std::vector<View> out;
  for (const auto& r : runners_) out.push_back({&r->campaign(), r->state(now), r->counters()});
  return out;
}

}  // namespace fleetgw::campaign
