#include "gateway/sim/scenario.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <toml++/toml.h>

#include "gateway/sim/route.h"
#include "gateway/sim/toml_number.h"
#include "motinova/faults.h"

namespace fleetgw::sim {
namespace {

// Reads one TOML table, remembering which keys were used so that finish() can reject the rest:
// a misspelt key ("sped_kmh") must fail loudly, not silently fall back to a default.
class TableReader {
 public:
  TableReader(const toml::table& table, std::string path, const std::string& file)
      : table_(table), path_(std::move(path)), file_(file) {}

  [[noreturn]] void fail(const toml::node* node, std::string_view key,
                         const std::string& what) const {
    const std::size_t line = node ? node->source().begin.line : table_.source().begin.line;
    const std::string full = key.empty() ? path_ : qualified(key);
    throw ScenarioError(file_, line, full, what);
  }

  const toml::node* get(std::string_view key) {
    used_.insert(std::string(key));
    return table_.get(key);
  }

  std::optional<double> number(std::string_view key, double lo, double hi) {
    const toml::node* n = get(key);
    if (!n) return std::nullopt;
    return read_number(*n, lo, hi, file_, qualified(key));
  }

  std::optional<int64_t> integer(std::string_view key, int64_t lo, int64_t hi) {
    const toml::node* n = get(key);
    if (!n) return std::nullopt;
    const auto i = n->value_exact<int64_t>();
    if (!i) fail(n, key, "expected an integer, got " + toml_type_name(*n));
    if (*i < lo || *i > hi) {
      fail(n, key,
           "expected an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got " +
               std::to_string(*i));
    }
    return *i;
  }

  std::optional<bool> boolean(std::string_view key) {
    const toml::node* n = get(key);
    if (!n) return std::nullopt;
    const auto b = n->value_exact<bool>();
    if (!b) fail(n, key, "expected true or false, got " + toml_type_name(*n));
    return *b;
  }

  std::optional<std::string> string(std::string_view key, std::size_t max_len = 256) {
    const toml::node* n = get(key);
    if (!n) return std::nullopt;
    const auto s = n->value_exact<std::string>();
    if (!s) fail(n, key, "expected a string, got " + toml_type_name(*n));
    if (s->size() > max_len) {
      fail(n, key, "string longer than " + std::to_string(max_len) + " characters");
    }
    return *s;
  }

  // A string restricted to printable ASCII (model-info fields are space-padded ASCII).
  std::optional<std::string> ascii(std::string_view key, std::size_t max_len) {
    auto s = string(key, max_len);
    if (s && !std::all_of(s->begin(), s->end(), [](char c) { return c >= 0x20 && c < 0x7F; })) {
      fail(table_.get(key), key, "only printable ASCII is allowed");
    }
    return s;
  }

  template <typename Enum, std::size_t N>
  std::optional<Enum> choice(std::string_view key,
                             const std::array<std::pair<std::string_view, Enum>, N>& options) {
    const toml::node* n = table_.get(key);
    const auto s = string(key);
    if (!s) return std::nullopt;
    std::string allowed;
    for (const auto& [name, value] : options) {
      if (name == *s) return value;
      allowed += (allowed.empty() ? "" : ", ") + std::string(name);
    }
    fail(n, key, "unknown value \"" + *s + "\" (expected one of: " + allowed + ")");
  }

  const toml::table* subtable(std::string_view key) {
    const toml::node* n = get(key);
    if (!n) return nullptr;
    if (!n->is_table()) fail(n, key, "expected a table, got " + toml_type_name(*n));
    return n->as_table();
  }

  const toml::array* array(std::string_view key) {
    const toml::node* n = get(key);
    if (!n) return nullptr;
    if (!n->is_array()) fail(n, key, "expected an array, got " + toml_type_name(*n));
    return n->as_array();
  }

  // Rejects every key that no getter asked for.
  void finish(std::string_view context = {}) const {
    for (const auto& [k, v] : table_) {
      if (used_.count(std::string(k.str())) == 0) {
        const std::size_t line =
            k.source().begin.line ? k.source().begin.line : v.source().begin.line;
        std::string what = "unknown key";
        if (!context.empty()) what += " (" + std::string(context) + ")";
        throw ScenarioError(file_, line, qualified(k.str()), what);
      }
    }
  }

  std::string qualified(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  const std::string& path() const { return path_; }
  const std::string& file() const { return file_; }
  const toml::table& table() const { return table_; }

 private:
  const toml::table& table_;
  std::string path_;
  const std::string& file_;
  std::set<std::string> used_;
};

// Days since 1970-01-01 of a civil date (H. Hinnant's algorithm).
int64_t days_from_civil(int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<int64_t>(doe) - 719468;
}

std::optional<uint8_t> assist_value(std::string_view name) {
  static constexpr std::array<std::pair<std::string_view, uint8_t>, 8> kNames{
      {{"off", 0x00},
       {"eco", 0x01},
       {"norm", 0x02},
       {"sport", 0x03},
       {"turbo", 0x04},
       {"walk", 0x05},
       {"special_22", 0x22},
       {"special_33", 0x33}}};
  for (const auto& [n, v] : kNames) {
    if (n == name) return v;
  }
  return std::nullopt;
}

bool valid_assist(int64_t v) {
  return (v >= 0 && v <= 5) || v == 0x22 || v == 0x33;
}

// assist = "norm" or assist = 2.
std::optional<uint8_t> read_assist(TableReader& r, std::string_view key) {
  const toml::node* n = r.get(key);
  if (!n) return std::nullopt;
  if (const auto s = n->value_exact<std::string>()) {
    if (const auto v = assist_value(*s)) return v;
    r.fail(n, key,
           "unknown assist level \"" + *s +
               "\" (expected off, eco, norm, sport, turbo, walk, special_22, special_33)");
  }
  if (const auto i = n->value_exact<int64_t>()) {
    if (valid_assist(*i)) return static_cast<uint8_t>(*i);
    r.fail(n, key, "assist level " + std::to_string(*i) + " is not one of 0..5, 0x22, 0x33");
  }
  r.fail(n, key, "expected an assist name or number, got " + toml_type_name(*n));
}

void read_device(TableReader& parent, std::string_view key, DeviceStrings& out) {
  const toml::table* t = parent.subtable(key);
  if (!t) return;
  TableReader r(*t, parent.qualified(key), parent.file());
  // 16 characters per field (spec §3.0); the FW string is conventionally Vx.x.x_YYYYMMDD.
  if (auto v = r.ascii("model", 16)) out.model = *v;
  if (auto v = r.ascii("serial", 16)) out.serial = *v;
  if (auto v = r.ascii("hw", 16)) out.hw = *v;
  if (auto v = r.ascii("fw", 16)) out.fw = *v;
  r.finish();
}

motinova::FaultSource fault_source_of(motinova::Node n) {
  switch (n) {
    case motinova::Node::kMc:
      return motinova::FaultSource::kMc;
    case motinova::Node::kBms:
      return motinova::FaultSource::kBms;
    case motinova::Node::kObc:
      return motinova::FaultSource::kObc;
    default:
      return motinova::FaultSource::kLock;
  }
}

bool is_sim_node(motinova::Node n) {
  return n == motinova::Node::kMc || n == motinova::Node::kBms || n == motinova::Node::kObc ||
         motinova::is_lock(n);
}

constexpr std::array<std::pair<std::string_view, Action>, 16> kActions{{
    {"fault", Action::kFault},
    {"clear", Action::kClear},
    {"jam_lock", Action::kJamLock},
    {"unjam_lock", Action::kUnjamLock},
    {"silence_node", Action::kSilenceNode},
    {"restore_node", Action::kRestoreNode},
    {"corrupt", Action::kCorrupt},
    {"garbage", Action::kGarbage},
    {"power_off", Action::kPowerOff},
    {"power_on", Action::kPowerOn},
    {"bms_auto_off", Action::kBmsAutoOff},
    {"lock", Action::kLock},
    {"unlock", Action::kUnlock},
    {"plug_charger", Action::kPlugCharger},
    {"unplug_charger", Action::kUnplugCharger},
    {"swap_battery", Action::kSwapBattery},
}};

motinova::Node read_node(TableReader& r, bool required, bool locks_only, const Scenario& scenario) {
  const toml::node* n = r.table().get("node");
  const auto s = r.string("node");
  if (!s) {
    if (required) r.fail(nullptr, "node", "missing key (this action needs a node)");
    return motinova::Node::kBroadcast;
  }
  const auto node = motinova::node_from_name(*s);
  if (!node || !is_sim_node(*node) || (locks_only && !motinova::is_lock(*node))) {
    r.fail(n, "node",
           "unknown node \"" + *s + "\" (expected " +
               (locks_only ? "lock1..lock5" : "mc, bms, obc, lock1..lock5") + ")");
  }
  if (motinova::is_lock(*node) &&
      !scenario.lock_fitted(static_cast<std::size_t>(motinova::lock_index(*node)))) {
    r.fail(n, "node", "\"" + *s + "\" is not fitted on this bike (bike.lock_kinds)");
  }
  return *node;
}

void read_fault_bits(TableReader& r, ScenarioEvent& ev, bool required) {
  const auto bits = r.integer("bits", 0, 0xFFFFFFFF);
  const toml::node* fn = r.table().get("fault");
  const auto name = r.string("fault");
  if (bits && name) r.fail(fn, "fault", "give either 'bits' or 'fault', not both");
  if (bits) {
    ev.bits = static_cast<uint32_t>(*bits);
  } else if (name) {
    const auto source = fault_source_of(ev.node);
    std::string known;
    for (const motinova::FaultDef& def : motinova::fault_table(source)) {
      if (def.name == *name) {
        ev.bits = def.mask;
        return;
      }
      known += (known.empty() ? "" : ", ") + std::string(def.name);
    }
    r.fail(fn, "fault",
           "unknown " + std::string(motinova::fault_source_name(source)) + " fault \"" + *name +
               "\" (known: " + known + ")");
  } else if (required) {
    r.fail(nullptr, "bits", "missing key (give 'bits' or 'fault')");
  }
  if (required && ev.bits == 0) r.fail(r.table().get("bits"), "bits", "must not be 0");
}

ScenarioEvent read_event(TableReader& r, const Scenario& scenario) {
  ScenarioEvent ev;
  ev.line = r.table().source().begin.line;
  const auto at = r.number("at_s", 0, 7 * 24 * 3600.0);
  if (!at) r.fail(nullptr, "at_s", "missing key");
  ev.at = Micros(static_cast<int64_t>(std::llround(*at * 1e6)));
  const auto action = r.choice("action", kActions);
  if (!action) r.fail(nullptr, "action", "missing key");
  ev.action = *action;
  const std::string context = "not used by action '" + std::string(action_name(ev.action)) + "'";
  switch (ev.action) {
    case Action::kFault:
    case Action::kClear:
      ev.node = read_node(r, true, false, scenario);
      read_fault_bits(r, ev, ev.action == Action::kFault);
      break;
    case Action::kJamLock:
    case Action::kUnjamLock:
    case Action::kLock:
    case Action::kUnlock:
      ev.node = read_node(r, true, true, scenario);
      break;
    case Action::kSilenceNode:
      ev.node = read_node(r, true, false, scenario);
      if (const auto d = r.number("duration_s", 0.001, 24 * 3600.0)) {
        ev.duration = Micros(static_cast<int64_t>(std::llround(*d * 1e6)));
      }
      break;
    case Action::kRestoreNode:
      ev.node = read_node(r, true, false, scenario);
      break;
    case Action::kCorrupt: {
      ev.node = read_node(r, false, false, scenario);
      static constexpr std::array<std::pair<std::string_view, Corruption>, 2> kKinds{
          {{"bitflip", Corruption::kBitFlip}, {"truncate", Corruption::kTruncate}}};
      ev.corruption = r.choice("kind", kKinds).value_or(Corruption::kBitFlip);
      ev.count = static_cast<uint32_t>(r.integer("count", 1, 100'000).value_or(1));
      break;
    }
    case Action::kGarbage:
      ev.count = static_cast<uint32_t>(r.integer("count", 1, 100'000).value_or(1));
      break;
    case Action::kPlugCharger: {
      const auto a = r.number("current_a", 0.1, 20);
      if (!a) r.fail(nullptr, "current_a", "missing key");
      ev.current_a = *a;
      break;
    }
    case Action::kSwapBattery: {
      const auto serial = r.ascii("serial", 16);
      if (!serial || serial->empty()) r.fail(nullptr, "serial", "missing key (the new BMS serial)");
      ev.serial = *serial;
      if (auto v = r.integer("soh_pct", 0, 100)) ev.soh_pct = static_cast<uint8_t>(*v);
      if (auto v = r.integer("cycles", 0, 65535)) ev.cycles = static_cast<uint16_t>(*v);
      if (auto v = r.number("soc_pct", 0, 100)) ev.soc_pct = *v;
      break;
    }
    case Action::kPowerOff:
    case Action::kPowerOn:
    case Action::kBmsAutoOff:
    case Action::kUnplugCharger:
      break;
  }
  r.finish(context);
  return ev;
}

void read_bike(TableReader& r, Scenario& s) {
  if (auto v = r.integer("seed", 0, std::numeric_limits<int64_t>::max())) {
    s.seed = static_cast<uint64_t>(*v);
  }
  if (auto v = r.number("soc_pct", 0, 100)) s.soc_pct = *v;
  if (auto v = r.number("odo_km", 0, 400'000'000)) s.odo_km = *v;  // u32 of 0.1 km
  if (auto v = r.integer("capacity_mah", 1000, 65535)) s.capacity_mah = static_cast<uint16_t>(*v);
  if (auto v = r.integer("cycles", 0, 65535)) s.cycles = static_cast<uint16_t>(*v);
  if (auto v = r.integer("soh_pct", 0, 100)) s.soh_pct = static_cast<uint8_t>(*v);
  // The 0x3408 offset can lower the limit by up to 50 km/h; 0x5408 carries it in one byte.
  if (auto v = r.number("speed_limit_kmh", 6, 60)) s.speed_limit_kmh = *v;
  if (auto v = r.integer("wheel_circumference_cm", 100, 255)) {
    s.wheel_circumference_cm = static_cast<uint8_t>(*v);
  }
  if (auto v = r.number("ambient_c", -30, 50)) s.ambient_c = *v;
  if (auto v = read_assist(r, "assist")) s.initial_assist = *v;
  if (auto v = r.boolean("headlight")) s.headlight = *v;
  if (auto v = r.boolean("vehicle_locked")) s.vehicle_locked = *v;
  if (auto v = r.boolean("locks_locked")) s.locks_locked = *v;
  if (auto v = r.boolean("iot_controls_acc")) s.iot_controls_acc = *v;
  if (auto v = r.boolean("mc_ignores_writes")) s.mc_ignores_writes = *v;
  if (const toml::array* kinds = r.array("lock_kinds")) {
    if (kinds->size() != kSimLocks) {
      r.fail(r.table().get("lock_kinds"), "lock_kinds",
             "expected 5 entries (LOCK 1..5, \"\" = not fitted), got " +
                 std::to_string(kinds->size()));
    }
    for (std::size_t i = 0; i < kSimLocks; ++i) {
      const toml::node& n = *kinds->get(i);
      const auto kind = n.value_exact<std::string>();
      const std::string key = "lock_kinds[" + std::to_string(i) + "]";
      if (!kind) r.fail(&n, key, "expected a string, got " + toml_type_name(n));
      if (kind->size() > 32) r.fail(&n, key, "lock kind longer than 32 characters");
      s.lock_kinds[i] = *kind;
    }
  }
  read_device(r, "mc", s.mc);
  read_device(r, "bms", s.bms);
  read_device(r, "obc", s.obc);
  read_device(r, "lock", s.lock);
  if (s.lock.serial.size() > 14) {
    r.fail(nullptr, "lock.serial", "at most 14 characters (the sim appends \"-n\" per lock)");
  }
  r.finish();
}

void read_scenario_table(TableReader& r, Scenario& s) {
  if (auto v = r.string("name", 64)) s.name = *v;
  if (auto v = r.string("description", 4096)) s.description = *v;
  if (auto v = r.number("duration_s", 1, 7 * 24 * 3600.0)) {
    s.duration = Micros(static_cast<int64_t>(std::llround(*v * 1e6)));
  }
  if (const toml::node* n = r.get("start_utc")) {
    const auto dt = n->value_exact<toml::date_time>();
    if (!dt || !dt->offset) {
      r.fail(n, "start_utc", "expected an offset date-time such as 2024-06-01T08:00:00Z");
    }
    const int64_t days = days_from_civil(dt->date.year, dt->date.month, dt->date.day);
    const int64_t secs = days * 86400 + dt->time.hour * 3600 + dt->time.minute * 60 +
                         dt->time.second - int64_t{dt->offset->minutes} * 60;
    if (secs < 0) r.fail(n, "start_utc", "must not be before 1970");
    s.start = Micros(secs * 1'000'000 + dt->time.nanosecond / 1000);
  }
  r.finish();
}

void read_bus(TableReader& r, Scenario& s) {
  static constexpr std::array<std::pair<std::string_view, motinova::CrcOrder>, 2> kCrc{
      {{"big", motinova::CrcOrder::kBig}, {"little", motinova::CrcOrder::kLittle}}};
  static constexpr std::array<std::pair<std::string_view, motinova::ByteOrder>, 2> kData{
      {{"big", motinova::ByteOrder::kBig}, {"little", motinova::ByteOrder::kLittle}}};
  if (auto v = r.choice("crc_order", kCrc)) s.crc_order = *v;
  if (auto v = r.choice("data_order", kData)) s.data_order = *v;
  r.finish();
}

}  // namespace

ScenarioError::ScenarioError(std::string file, std::size_t line, std::string key,
                             const std::string& what)
    : std::runtime_error(file + (line ? ":" + std::to_string(line) : std::string()) + ": " +
                         (key.empty() ? std::string() : key + ": ") + what),
      file_(std::move(file)),
      line_(line),
      key_(std::move(key)) {}

std::string_view action_name(Action a) {
  for (const auto& [name, value] : kActions) {
    if (value == a) return name;
  }
  return "?";
}

Micros Scenario::ride_duration() const {
  double total = 0;
  for (const RideSegment& seg : ride) total += seg.duration_s;
  return Micros(static_cast<int64_t>(std::llround(total * 1e6)));
}

Micros Scenario::effective_duration() const {
  if (duration.count() > 0) return duration;
  Micros end = ride_duration();
  for (const ScenarioEvent& ev : events) end = std::max(end, ev.at + ev.duration);
  return end + Micros(60'000'000);
}

Scenario parse_scenario(std::string_view toml_text, std::string_view source_name) {
  const std::string file(source_name);
  toml::table root;
  try {
    root = toml::parse(toml_text, source_name);
  } catch (const toml::parse_error& e) {
    throw ScenarioError(file, e.source().begin.line, "", std::string(e.description()));
  }

  Scenario s;
  s.source = file;
  TableReader top(root, "", file);
  if (const toml::table* t = top.subtable("scenario")) {
    TableReader r(*t, "scenario", file);
    read_scenario_table(r, s);
  }
  // [bike] before the events: events are checked against the fitted locks.
  if (const toml::table* t = top.subtable("bike")) {
    TableReader r(*t, "bike", file);
    read_bike(r, s);
  }
  if (const toml::table* t = top.subtable("bus")) {
    TableReader r(*t, "bus", file);
    read_bus(r, s);
  }
  if (const toml::array* ride = top.array("ride")) {
    for (std::size_t i = 0; i < ride->size(); ++i) {
      const toml::node& n = *ride->get(i);
      const std::string path = "ride[" + std::to_string(i) + "]";
      if (!n.is_table()) {
        throw ScenarioError(file, n.source().begin.line, path,
                            "expected a table ([[ride]]), got " + toml_type_name(n));
      }
      TableReader r(*n.as_table(), path, file);
      RideSegment seg;
      seg.line = n.source().begin.line;
      const auto d = r.number("duration_s", 0.1, 24 * 3600.0);
      if (!d) r.fail(nullptr, "duration_s", "missing key");
      seg.duration_s = *d;
      const auto v = r.number("speed_kmh", 0, 60);
      if (!v) r.fail(nullptr, "speed_kmh", "missing key");
      seg.speed_kmh = *v;
      seg.assist = read_assist(r, "assist");
      seg.grade_pct = r.number("grade_pct", -20, 20).value_or(0);
      r.finish();
      s.ride.push_back(seg);
    }
  }
  if (const toml::array* events = top.array("event")) {
    for (std::size_t i = 0; i < events->size(); ++i) {
      const toml::node& n = *events->get(i);
      const std::string path = "event[" + std::to_string(i) + "]";
      if (!n.is_table()) {
        throw ScenarioError(file, n.source().begin.line, path,
                            "expected a table ([[event]]), got " + toml_type_name(n));
      }
      TableReader r(*n.as_table(), path, file);
      // repeat_every_s / repeat_count: the same event again and again (worst-case.toml changes
      // a lock's state every second for an hour) without thousands of [[event]] tables.
      const auto every = r.number("repeat_every_s", 0.01, 24 * 3600.0);
      const auto count = r.integer("repeat_count", 1, 1'000'000);
      if (every.has_value() != count.has_value()) {
        r.fail(nullptr, every ? "repeat_count" : "repeat_every_s",
               "missing key (repeat_every_s and repeat_count go together)");
      }
      const ScenarioEvent ev = read_event(r, s);
      s.events.push_back(ev);
      for (int64_t k = 1; k < count.value_or(1); ++k) {
        ScenarioEvent copy = ev;
        copy.at +=
            Micros(static_cast<int64_t>(std::llround(*every * 1e6 * static_cast<double>(k))));
        s.events.push_back(copy);
      }
    }
  }
  if (const toml::array* route = top.array("route")) s.route = parse_route(*route, file);
  top.finish();
  std::stable_sort(s.events.begin(), s.events.end(),
                   [](const ScenarioEvent& a, const ScenarioEvent& b) { return a.at < b.at; });
  return s;
}

Scenario load_scenario(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ScenarioError(path.string(), 0, "", "cannot open scenario file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ScenarioError(path.string(), 0, "", "cannot read scenario file");
  return parse_scenario(text.str(), path.string());
}

std::filesystem::path bundled_scenario_dir() {
  return std::filesystem::path(FLEETGW_SOURCE_DIR) / "config" / "scenarios";
}

}  // namespace fleetgw::sim
