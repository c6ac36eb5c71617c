#include "gateway/domain/pack_tracker.h"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <utility>

#include "gateway/domain/payloads.h"
#include "motinova/catalogue.h"

namespace fleetgw::domain {
namespace {

bool is_counter(std::string_view field) {
  return field == "cycles" || field.ends_with("_count");
}

std::optional<int64_t> whole(std::optional<double> v) {
  if (!v) return std::nullopt;
  return static_cast<int64_t>(std::llround(*v));
}

}  // namespace

PackTracker::PackTracker(PackConfig config, DomainSink& sink)
    : config_(std::move(config)), sink_(sink) {}

void PackTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return;
  const std::string_view name = msg.desc->name;
  const motinova::Node src = msg.desc->source();
  if (src != motinova::Node::kBms) return;

  if (name == "bms_status") {
    const std::optional<Reading> old_cycles = cycles_;
    update(voltage_, msg, "voltage_v", now);
    update(current_, msg, "current_a", now);
    update(soc_, msg, "soc_pct", now);
    update(soh_, msg, "soh_pct", now);
    update(cycles_, msg, "cycles", now);
    update(remaining_, msg, "remaining_mah", now);
    update(full_, msg, "full_mah", now);
    update(temp_, msg, "temp_c", now);
    if (!next_due_) next_due_ = now + config_.settle;
    if (old_cycles && cycles_ && old_cycles->value != cycles_->value) snapshot(now);
  } else if (name == "bms_cells") {
    cells_mv_.clear();
    for (std::size_t i = 0; i < 16; ++i) {
      const auto mv = msg.element("cells_mv", i);
      cells_mv_.push_back(mv ? static_cast<int>(*mv) : 0);
    }
    // Unpopulated cells are 0; keep the positions of populated ones (1-based index matters).
    while (!cells_mv_.empty() && cells_mv_.back() == 0) cells_mv_.pop_back();
    cells_at_ = now;
  } else if (name == "bms_temps") {
    update(temp_max_, msg, "temp_max_c", now);
    update(temp_min_, msg, "temp_min_c", now);
  } else if (name == "pack_stats") {
    nlohmann::json all = nlohmann::json::object();
    nlohmann::json counters = nlohmann::json::object();
    for (const motinova::FieldValue& v : msg.values()) {
      if (v.field == nullptr || v.field->kind == motinova::FieldKind::kReserved) continue;
      const std::string key(v.field->name);
      if (!v.valid) {
        all[key] = nullptr;
        continue;
      }
      all[key] = v.field->scale == 1.0 ? nlohmann::json(static_cast<int64_t>(std::llround(v.value)))
                                       : nlohmann::json(v.value);
      if (is_counter(key)) counters[key] = v.raw;
    }
    lifetime_ = std::move(all);
    const bool changed = counters_ && *counters_ != counters;
    counters_ = std::move(counters);
    if (changed) snapshot(now);
  } else if (name == "device_info") {
    if (const auto serial = msg.text("serial"); !serial.empty()) serial_ = std::string(serial);
  }
}

void PackTracker::tick(Micros now) {
  if (next_due_ && now >= *next_due_) {
    // Only while the BMS talks: a snapshot of stale values would be noise.
    if (fresh(voltage_, now, config_.stale)) snapshot(now);
    next_due_ = now + config_.period;
  }
}

void PackTracker::snapshot(Micros now) {
  PackReading r;
  storage::PackSnapshotRow& s = r.snapshot;
  s.ts_us = now.count();
  s.voltage_v = fresh(voltage_, now, config_.stale);
  s.current_a = fresh(current_, now, config_.stale);
  s.soc_pct = fresh(soc_, now, config_.stale);
  s.soh_pct = fresh(soh_, now, config_.stale);
  s.cycles = whole(fresh(cycles_, now, config_.stale));
  for (const auto* t : {&temp_, &temp_max_, &temp_min_}) {
    if (const auto v = fresh(*t, now, config_.stale)) s.temps_c.push_back(*v);
  }
  if (!cells_mv_.empty() && now - cells_at_ <= config_.stale) {
    int lo = -1, hi = -1;
    for (std::size_t i = 0; i < cells_mv_.size(); ++i) {
      const int mv = cells_mv_[i];
      if (mv <= 0) continue;
      if (lo < 0 || mv < cells_mv_[static_cast<std::size_t>(lo)]) lo = static_cast<int>(i);
      if (hi < 0 || mv > cells_mv_[static_cast<std::size_t>(hi)]) hi = static_cast<int>(i);
      r.cells_mv.push_back(mv);
    }
    if (lo >= 0) {
      s.cell_min_mv = cells_mv_[static_cast<std::size_t>(lo)];
      s.cell_max_mv = cells_mv_[static_cast<std::size_t>(hi)];
      s.cell_spread_mv = *s.cell_max_mv - *s.cell_min_mv;
      s.cell_min_index = lo + 1;
      s.cell_max_index = hi + 1;
    }
  }
  s.lifetime_json = lifetime_.dump();
  r.remaining_mah = fresh(remaining_, now, config_.stale);
  r.full_mah = fresh(full_, now, config_.stale);
  r.serial = serial_;
  storage::Bytes payload = pack_payload(r);
  sink_.batch().packs.push_back({std::move(r.snapshot), std::move(payload)});
  ++snapshots_;
}

}  // namespace fleetgw::domain
