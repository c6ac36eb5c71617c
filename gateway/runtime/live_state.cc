#include "gateway/runtime/live_state.h"

#include <fmt/format.h>

#include <bit>

#include "motinova/fault_names.h"
#include "motinova/faults.h"

namespace fleetgw::runtime {

void LiveState::update(const motinova::DecodedMessage& m, const motinova::DecodeOptions& options) {
  ++messages;
  if (!m.desc) return;
  const std::string_view name = m.desc->name;
  const motinova::Node src = m.desc->source();
  if (name == "mc_status") {
    speed_kmh = m.number("speed_kmh");
    if (const auto* f = m.find("assist"); f && f->valid) {
      assist = f->text.empty() ? fmt::format("0x{:02X}", f->raw) : std::string(f->text);
      assist_raw = f->raw;
    }
    if (auto r = m.number("range_km")) range_km = r;
    if (auto h = m.number("headlight")) headlight = *h != 0.0;
    if (!pack_voltage_v) pack_voltage_v = m.number("voltage_v");
    if (auto t = m.number("motor_temp_c")) motor_temp_c = t;
    if (auto o = m.number("odo_km"); o && !odo_km) odo_km = o;
  } else if (name == "mc_settings") {
    auto limit = m.number("speed_limit_kmh");
    const auto offset = m.number("speed_limit_offset_kmh");
    // A report without an offset field (older MC firmware) states the limit in force itself.
    if (limit && offset && settings_limit_is_factory) limit = *limit + *offset;
    if (limit) speed_limit_kmh = limit;
  } else if (name == "mc_odometer") {
    odo_km = m.number("odo_km");
  } else if (name == "bms_status") {
    soc_pct = m.number("soc_pct");
    pack_voltage_v = m.number("voltage_v");
    pack_current_a = m.number("current_a");
    if (auto c = m.number("charging")) charging = *c != 0.0;
  } else if (name == "lock_status" && motinova::is_lock(src)) {
    auto& lock = locks[static_cast<std::size_t>(motinova::lock_index(src))];
    lock.kind = options.lock_kinds[static_cast<std::size_t>(motinova::lock_index(src))];
    if (const auto* f = m.find("state"); f && f->valid) {
      lock.state_raw = static_cast<int>(f->raw);
      lock.state = f->text.empty() ? fmt::format("state_{}", f->raw) : std::string(f->text);
    }
  } else if (m.desc->kind == motinova::MessageKind::kFaultWord) {
    auto& list = per_node_[static_cast<std::size_t>(src) & 0xF];
    list.clear();
    if (const auto* f = m.find("raw"); f && f->valid) {
      motinova::for_each_active_fault(
          m.desc->fault_source, static_cast<uint32_t>(f->raw), options,
          [&](uint32_t mask, const motinova::FaultDef* def) {
            ActiveFault a;
            a.node = std::string(motinova::node_name(src));
            if (def) {
              a.code = def->code;
              a.name = std::string(def->name);
              a.severity = std::string(motinova::severity_name(def->severity));
            } else {
              a.name = fmt::format("undefined_bit_{}", std::countr_zero(mask));
              a.severity = "warning";
            }
            list.push_back(std::move(a));
          });
    }
    rebuild_faults();
  }
}

void LiveState::rebuild_faults() {
  faults.clear();
  for (const auto& list : per_node_) faults.insert(faults.end(), list.begin(), list.end());
}

std::string LiveState::line() const {
  auto num = [](const std::optional<double>& v, const char* fmt_spec, const char* unit) {
    return v ? fmt::format(fmt::runtime(fmt_spec), *v) + unit : std::string("--") + unit;
  };
  std::string out =
      fmt::format("{:>9} | {:<6} | SOC {:>5} | {:>7} {:>8}", num(speed_kmh, "{:.1f}", " km/h"),
                  assist.value_or("--"), num(soc_pct, "{:.0f}", "%"),
                  num(pack_voltage_v, "{:.1f}", " V"), num(pack_current_a, "{:+.1f}", " A"));
  if (charging && *charging) out += " charging";
  out += " |";
  for (const auto& l : locks) {
    if (l.kind.empty() || l.state_raw < 0) continue;
    out += fmt::format(" {}:{}", l.kind, l.state);
  }
  out += " | faults: ";
  if (faults.empty()) {
    out += "none";
  } else {
    for (std::size_t i = 0; i < faults.size(); ++i) {
      const auto& f = faults[i];
      out += fmt::format("{}{}.{}{}", i ? ", " : "", f.node, f.name,
                         f.code >= 0 ? fmt::format("({})", f.code) : "");
    }
  }
  return out;
}

}  // namespace fleetgw::runtime
