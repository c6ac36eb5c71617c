#include "gateway/config/config.h"

#include <fmt/format.h>

#include <toml++/toml.h>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "motinova/fault_names.h"

namespace fleetgw::config {
namespace {

std::string join(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) {
    if (!out.empty()) out += "\n";
    out += l;
  }
  return out;
}

// Reads one [table] of the file, remembering which keys were consumed so that the rest can be
// reported as unknown.
class Section {
 public:
  Section(const toml::table* table, std::string path, std::string file,
          std::vector<std::string>& problems, std::map<std::string, int, std::less<>>& lines)
      : table_(table),
        path_(std::move(path)),
        file_(std::move(file)),
        problems_(problems),
        lines_(lines) {}

  ~Section() { report_unknown(); }
  Section(const Section&) = delete;
  Section& operator=(const Section&) = delete;

  // A nested [a.b] table.
  Section sub(std::string_view key) {
    seen_.insert(std::string(key));
    const toml::table* t = nullptr;
    if (table_) {
      if (const toml::node* n = table_->get(key)) {
        t = n->as_table();
        if (!t) problem(*n, key, "expected a table");
      }
    }
    return Section(t, qualify(key), file_, problems_, lines_);
  }

  void string(std::string_view key, std::string& out) {
    if (const toml::node* n = find(key)) {
      if (auto v = n->value<std::string>(); v && n->is_string()) {
        out = *v;
      } else {
        problem(*n, key, "expected a string");
      }
    }
  }

  void choice(std::string_view key, std::string& out,
              std::initializer_list<std::string_view> allowed) {
    std::string value = out;
    const toml::node* n = find(key);
    if (!n) return;
    string(key, value);
    for (auto a : allowed) {
      if (a == value) {
        out = value;
        return;
      }
    }
    std::string list;
    for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    problem(*n, key, fmt::format("expected one of {}, got \"{}\"", list, value));
  }

  template <typename Int>
  void integer(std::string_view key, Int& out, int64_t min, int64_t max) {
    if (const toml::node* n = find(key)) {
      if (!n->is_integer()) {
        problem(*n, key, "expected an integer");
        return;
      }
      const int64_t v = *n->value<int64_t>();
      if (v < min || v > max) {
        problem(*n, key, fmt::format("{} is out of range [{}, {}]", v, min, max));
        return;
      }
      out = static_cast<Int>(v);
    }
  }

  void number(std::string_view key, double& out, double min, double max) {
    if (const toml::node* n = find(key)) {
      if (!n->is_number()) {
        problem(*n, key, "expected a number");
        return;
      }
      const double v = *n->value<double>();
      if (!std::isfinite(v)) {
        // nan compares false with everything, so the range check alone would let it through.
        problem(*n, key, fmt::format("{} is not a finite number", v));
        return;
      }
      if (v < min || v > max) {
        problem(*n, key, fmt::format("{} is out of range [{}, {}]", v, min, max));
        return;
      }
      out = v;
    }
  }

  void boolean(std::string_view key, bool& out) {
    if (const toml::node* n = find(key)) {
      if (!n->is_boolean()) {
        problem(*n, key, "expected true or false");
        return;
      }
      out = *n->value<bool>();
    }
  }

  // Up to 8 integers in [min, max], strictly descending (thresholds).
  void descending_integers(std::string_view key, std::vector<int>& out, int min, int max) {
    const toml::node* n = find(key);
    const toml::array* a = n ? n->as_array() : nullptr;
    std::vector<int> v;
    for (std::size_t i = 0; a && i < a->size() && i < 8; ++i) {
      const auto x = (*a)[i].value<int64_t>();
      if (!(*a)[i].is_integer() || *x < min || *x > max || (i > 0 && *x >= v.back())) break;
      v.push_back(static_cast<int>(*x));
    }
    if (a && v.size() == a->size()) {
      out = std::move(v);
    } else if (n) {
      problem(*n, key, fmt::format("expected up to 8 integers in [{}, {}], descending", min, max));
    }
  }

  template <std::size_t N>
  void string_array(std::string_view key, std::array<std::string, N>& out, bool allow_empty) {
    const toml::node* n = find(key);
    if (!n) return;
    const toml::array* a = n->as_array();
    if (!a || a->size() != N) {
      problem(*n, key, fmt::format("expected an array of {} strings", N));
      return;
    }
    std::array<std::string, N> values;
    for (std::size_t i = 0; i < N; ++i) {
      const auto* s = (*a)[i].as_string();
      if (!s || (!allow_empty && s->get().empty())) {
        problem(*n, key,
                fmt::format("element {} must be a{} string", i, allow_empty ? "" : " non-empty"));
        return;
      }
      values[i] = s->get();
    }
    out = values;
  }

  // An array of up to `max` distinct ids (1..64 of [A-Za-z0-9._-]), e.g. [vehicle] groups.
  void id_list(std::string_view key, std::vector<std::string>& out, std::size_t max) {
    const toml::node* n = find(key);
    if (!n) return;
    const toml::array* a = n->as_array();
    if (!a || a->size() > max) {
      problem(*n, key, fmt::format("expected an array of at most {} strings", max));
      return;
    }
    std::vector<std::string> values;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const auto* s = (*a)[i].as_string();
      const bool ok = s && !s->get().empty() && s->get().size() <= 64 &&
                      s->get().find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                                 "0123456789._-") == std::string::npos;
      if (!ok) {
        problem(*n, key, fmt::format("element {} must be 1..64 characters of [A-Za-z0-9._-]", i));
        return;
      }
      if (std::find(values.begin(), values.end(), s->get()) != values.end()) {
        problem(*n, key, fmt::format("element {} ('{}') is repeated", i, s->get()));
        return;
      }
      values.push_back(s->get());
    }
    out = std::move(values);
  }

  // Every key of a free-form table of strings (e.g. trusted keys).
  void string_map(std::map<std::string, std::string>& out) {
    if (!table_) return;
    for (const auto& [k, v] : *table_) {
      seen_.insert(std::string(k.str()));
      lines_[qualify(k.str())] = static_cast<int>(v.source().begin.line);
      if (!v.is_string()) {
        problem(v, k.str(), "expected a string");
        continue;
      }
      out[std::string(k.str())] = *v.value<std::string>();
    }
  }

  // Reports a problem with a value that passed the type check but is inconsistent.
  void invalid(std::string_view key, std::string_view what) {
    if (const toml::node* n = table_ ? table_->get(key) : nullptr) problem(*n, key, what);
  }

 private:
  const toml::node* find(std::string_view key) {
    seen_.insert(std::string(key));
    const toml::node* n = table_ ? table_->get(key) : nullptr;
    if (n) lines_[qualify(key)] = static_cast<int>(n->source().begin.line);
    return n;
  }
  std::string qualify(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  void problem(const toml::node& n, std::string_view key, std::string_view what) {
    problems_.push_back(
        fmt::format("{}:{}: {}: {}", file_, n.source().begin.line, qualify(key), what));
  }
  void report_unknown() {
    if (!table_) return;
    for (const auto& [k, v] : *table_) {
      if (!seen_.count(std::string(k.str()))) {
        problems_.push_back(
            fmt::format("{}:{}: {}: unknown key", file_, v.source().begin.line, qualify(k.str())));
      }
    }
  }

  const toml::table* table_;
  std::string path_;
  std::string file_;
  std::vector<std::string>& problems_;
  std::map<std::string, int, std::less<>>& lines_;
  std::set<std::string> seen_;
};

// Fault-bit names of one source, e.g. [protocol.mc_fault_names] low_0x0080 = "..." (U6, U18,
// U20, U22).
void read_fault_names(Section& protocol, std::string_view key, motinova::FaultSource source,
                      motinova::DecodeOptions& p) {
  auto table = protocol.sub(key);
  std::map<std::string, std::string> names;
  table.string_map(names);
  for (const auto& [bit, name] : names) {
    if (const std::string why = set_fault_name(p, source, bit, name); !why.empty()) {
      table.invalid(bit, why);
    }
  }
}

void read_protocol(Section& s, motinova::DecodeOptions& p, std::vector<std::string>& problems) {
  std::string crc = "be", data = "be", mc = "documented", bms = "documented", other = "documented",
              vi = "voltage_first", answer = "0x713", wheel = "circumference_cm", adjust = "cm",
              currents = "discharge_first", time_unit = "h";
  s.choice("crc_order", crc, {"be", "le", "auto"});
  s.choice("data_order", data, {"be", "le"});
  s.choice("mc_fault_layout", mc, {"documented", "swapped", "two_words_low_first"});
  s.choice("bms_fault_layout", bms, {"documented", "swapped", "two_words_low_first"});
  s.choice("other_fault_layout", other, {"documented", "swapped", "two_words_low_first"});
  s.choice("mc_voltage_current_order", vi, {"voltage_first", "current_first", "auto"});
  s.choice("mc_answer_id", answer, {"0x713", "0x716", "0x710", "auto"});
  s.choice("wheel_size_unit", wheel, {"circumference_cm", "diameter_cm", "diameter_inch"});
  s.choice("wheel_adjust_unit", adjust, {"cm", "mm"});
  s.choice("pack_stats_currents", currents, {"discharge_first", "charge_first"});
  s.choice("pack_stats_time_unit", time_unit, {"h", "min"});
  p.crc_order = parse_crc_order(crc);
  p.data_order = parse_byte_order(data);
  p.mc_fault_layout = parse_fault_layout(mc);
  p.bms_fault_layout = parse_fault_layout(bms);
  p.other_fault_layout = parse_fault_layout(other);
  p.mc_voltage_current_order = parse_mc_vi_order(vi);
  p.mc_answer_id = parse_mc_answer_id(answer);
  p.wheel_size_unit = parse_wheel_size_unit(wheel);
  p.wheel_adjust_unit = parse_wheel_adjust_unit(adjust);
  p.pack_stats_discharge_current_first = currents == "discharge_first";
  p.pack_stats_time_unit =
      time_unit == "min" ? motinova::PackTimeUnit::kMinutes : motinova::PackTimeUnit::kHours;
  s.boolean("bms_current_charge_positive", p.bms_current_charge_positive);
  s.boolean("mc_current_signed", p.mc_current_signed);
  s.string_array("lock_state_names", p.lock_state_names, false);
  s.string_array("lock_kinds", p.lock_kinds, true);
  {
    std::array<std::string, motinova::kPackStatsCounters> order = p.pack_stats_counter_order;
    s.string_array("pack_stats_counter_order", order, false);
    if (const std::string why = set_pack_stats_counter_order(p, {order.begin(), order.end()});
        !why.empty()) {
      s.invalid("pack_stats_counter_order", why);
    }
  }
  {
    auto assist = s.sub("assist_names");
    std::map<std::string, std::string> names;
    assist.string_map(names);
    for (const auto& [value, name] : names) {
      if (const std::string why = set_assist_name(p, value, name); !why.empty()) {
        assist.invalid(value, why);
      }
    }
  }
  read_fault_names(s, "mc_fault_names", motinova::FaultSource::kMc, p);
  read_fault_names(s, "bms_fault_names", motinova::FaultSource::kBms, p);
  read_fault_names(s, "iot_fault_names", motinova::FaultSource::kIot, p);
  read_fault_names(s, "lock_fault_names", motinova::FaultSource::kLock, p);
  (void)problems;
}

Config parse_root(const toml::table& root, const std::string& name) {
  std::vector<std::string> problems;
  Config c;
  c.display_name = name;
  {
    Section top(&root, "", name, problems, c.key_lines);
    {
      auto s = top.sub("vehicle");
      s.string("id", c.vehicle.id);
      // The rule the command verifier and the uplink apply (one topic level, the MQTT client id).
      const bool id_ok = !c.vehicle.id.empty() && c.vehicle.id.size() <= 64 &&
                         c.vehicle.id.find_first_not_of(
                             "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-") ==
                             std::string::npos;
      if (!id_ok) s.invalid("id", "must be 1..64 characters of [A-Za-z0-9._-]");
      s.id_list("groups", c.vehicle.groups, 32);
      s.string("type_id", c.vehicle.type_id);
      if (c.vehicle.type_id.size() > 64) s.invalid("type_id", "must be at most 64 bytes");
    }
    {
      auto s = top.sub("log");
      s.choice("level", c.log.level,
               {"trace", "debug", "info", "warn", "error", "critical", "off"});
    }
    {
      auto s = top.sub("can");
      s.choice("transport", c.can.transport, {"socketcan", "replay", "udp", "sim"});
      s.string("interface", c.can.interface);
      s.string("replay_file", c.can.replay_file);
      s.number("replay_speed", c.can.replay_speed, 0.0, 1e6);
      s.string("udp_local", c.can.udp_local);
      s.string("udp_remote", c.can.udp_remote);
      s.integer("reassembly_gap_ms", c.can.reassembly_gap_ms, 10, 10'000);
    }
    {
      auto s = top.sub("protocol");
      read_protocol(s, c.protocol, problems);
    }
    {
      auto s = top.sub("node");
      s.string("model", c.node.identity.model);
      s.string("serial", c.node.identity.serial);
      s.string("hw", c.node.identity.hw);
      for (auto [key, value] :
           {std::pair{"model", &c.node.identity.model},
            std::pair{"serial", &c.node.identity.serial}, std::pair{"hw", &c.node.identity.hw}}) {
        if (value->size() > 16) s.invalid(key, "at most 16 ASCII characters (model-info block)");
      }
      s.integer("offline_timeout_ms", c.node.offline_timeout_ms, 200, 600'000);
      s.integer("fault_stale_ms", c.node.fault_stale_ms, 200, 600'000);
      s.integer("request_retry_ms", c.node.request_retry_ms, 10, 10'000);
      s.integer("request_timeout_ms", c.node.request_timeout_ms, 50, 60'000);
      s.integer("model_info_period_ms", c.node.model_info_period_ms, 100, 3'600'000);
      s.integer("lock_status_poll_ms", c.node.lock_status_poll_ms, 100, 3'600'000);
      s.integer("bms_poll_ms", c.node.bms_poll_ms, 100, 3'600'000);
      s.integer("pack_stats_poll_ms", c.node.pack_stats_poll_ms, 1000, 86'400'000);
      s.boolean("answer_mc_handshake", c.node.answer_mc_handshake);
    }
    {
      auto s = top.sub("sim");
      s.string("scenario", c.sim.scenario);
      s.number("speed", c.sim.speed, 0.01, 100'000);
      s.integer("seed", c.sim.seed, 0, INT64_MAX);
      s.boolean("start_now", c.sim.start_now);
      s.string("nmea_pty", c.sim.nmea_pty);
      s.boolean("lockstep", c.sim.lockstep);
    }
    {
      auto s = top.sub("storage");
      s.string("path", c.storage.path);
      s.integer("max_mb", c.storage.max_mb, 1, 1'000'000);
      s.choice("synchronous", c.storage.synchronous, {"normal", "full"});
      s.integer("flush_ms", c.storage.flush_ms, 10, 60'000);
    }
    {
      auto s = top.sub("mqtt");
      s.boolean("enabled", c.mqtt.enabled);
      s.string("uri", c.mqtt.uri);
      s.string("topic_prefix", c.mqtt.topic_prefix);
      s.string("ca_file", c.mqtt.ca_file);
      s.string("cert_file", c.mqtt.cert_file);
      s.string("key_file", c.mqtt.key_file);
      s.string("username", c.mqtt.username);
      s.string("password", c.mqtt.password);
      s.boolean("verify_server", c.mqtt.verify_server);
      s.integer("keepalive_s", c.mqtt.keepalive_s, 5, 3600);
      s.boolean("tcp_nodelay", c.mqtt.tcp_nodelay);
      s.integer("max_inflight", c.mqtt.max_inflight, 1, 10'000);
      s.integer("qos", c.mqtt.qos, 0, 1);
      s.integer("telemetry_qos", c.mqtt.telemetry_qos, 0, 1);
      s.integer("live_telemetry_max_age_ms", c.mqtt.live_telemetry_max_age_ms, 0, 86'400'000);
      s.integer("status_interval_ms", c.mqtt.status_interval_ms, 0, 86'400'000);
      s.integer("state_interval_ms", c.mqtt.state_interval_ms, 0, 3'600'000);
      s.number("state_min_move_m", c.mqtt.state_min_move_m, 0.0, 100'000.0);
      s.integer("batch_max_samples", c.mqtt.batch_max_samples, 1, 10'000);
      s.integer("batch_max_ms", c.mqtt.batch_max_ms, 0, 3'600'000);
      s.integer("reconnect_min_ms", c.mqtt.reconnect_min_ms, 10, 3'600'000);
      s.integer("reconnect_max_ms", c.mqtt.reconnect_max_ms, 10, 3'600'000);
      s.choice("protocol", c.mqtt.protocol, {"5", "3.1.1"});
      // MQTT 5 carries both as four-byte intervals (0xFFFFFFFF = the session never expires).
      s.integer("session_expiry_s", c.mqtt.session_expiry_s, 0, 4'294'967'295);
      s.integer("will_delay_s", c.mqtt.will_delay_s, 0, 4'294'967'295);
      if (c.mqtt.uri.rfind("tcp://", 0) != 0 && c.mqtt.uri.rfind("ssl://", 0) != 0 &&
          c.mqtt.uri.rfind("mqtts://", 0) != 0 && c.mqtt.uri.rfind("mqtt://", 0) != 0) {
        s.invalid("uri", "must start with tcp://, mqtt://, ssl:// or mqtts://");
      }
      if ((c.mqtt.cert_file.empty()) != (c.mqtt.key_file.empty())) {
        s.invalid(c.mqtt.cert_file.empty() ? "key_file" : "cert_file",
                  "cert_file and key_file go together (mutual TLS)");
      }
    }
    {
      auto s = top.sub("telemetry");
      s.integer("riding_interval_ms", c.telemetry.riding_interval_ms, 100, 3'600'000);
      s.integer("parked_interval_ms", c.telemetry.parked_interval_ms, 1000, 86'400'000);
    }
    {
      auto s = top.sub("ride");
      s.number("moving_speed_kmh", c.ride.moving_speed_kmh, 0.1, 50);
      s.integer("stationary_end_s", c.ride.stationary_end_s, 10, 86'400);
    }
    {
      auto s = top.sub("faults");
      s.integer("debounce_ms", c.faults.debounce_ms, 0, 600'000);
    }
    {
      auto s = top.sub("alarms");
      s.boolean("enabled", c.alarms.enabled);
      s.number("movement_speed_kmh", c.alarms.movement_speed_kmh, 0.1, 30);
      s.number("movement_rpm", c.alarms.movement_rpm, 1, 1000);
      s.integer("movement_debounce_ms", c.alarms.movement_debounce_ms, 0, 60'000);
      s.integer("movement_clear_s", c.alarms.movement_clear_s, 1, 3600);
      s.descending_integers("low_battery_pct", c.alarms.low_battery_pct, 1, 99);
      s.number("low_battery_hysteresis_pct", c.alarms.low_battery_hysteresis_pct, 0, 50);
      s.integer("battery_silent_ms", c.alarms.battery_silent_ms, 1000, 3'600'000);
    }
    {
      auto s = top.sub("parked");
      s.boolean("enabled", c.parked.enabled);
      s.integer("settle_s", c.parked.settle_s, 1, 3600);
      s.integer("poll_interval_ms", c.parked.poll_interval_ms, 5000, 86'400'000);
      s.integer("telemetry_batch_ms", c.parked.telemetry_batch_ms, 0, 3'600'000);
      s.integer("stale_poll_ms", c.parked.stale_poll_ms, 100, 60'000);
      if (c.parked.stale_poll_ms >= std::min(c.node.fault_stale_ms, c.node.offline_timeout_ms)) {
        s.invalid("stale_poll_ms",
                  "must be below node.fault_stale_ms and node.offline_timeout_ms (a node that "
                  "must be polled would be taken for a silent one)");
      }
    }
    {
      auto s = top.sub("gnss");
      s.boolean("enabled", c.gnss.enabled);
      s.string("gpsd", c.gnss.gpsd);
      s.integer("max_age_ms", c.gnss.max_age_ms, 200, 600'000);
      s.integer("reconnect_max_ms", c.gnss.reconnect_max_ms, 1000, 3'600'000);
    }
    {
      auto s = top.sub("geofence");
      s.boolean("enabled", c.geofence.enabled);
      s.string("bundle_file", c.geofence.bundle_file);
      s.number("margin_m", c.geofence.margin_m, 0, 500);
      s.integer("min_dwell_ms", c.geofence.min_dwell_ms, 0, 600'000);
      s.integer("speed_ramp_ms", c.geofence.speed_ramp_ms, 0, 600'000);
      s.integer("assist_fade_ms", c.geofence.assist_fade_ms, 0, 600'000);
      s.integer("restore_ramp_ms", c.geofence.restore_ramp_ms, 0, 600'000);
      s.integer("own_limit_kmh", c.geofence.own_limit_kmh, 1, 255);
      s.boolean("refuse_ride_ending_locks", c.geofence.refuse_ride_ending_locks);
      s.string("bundle_topic", c.geofence.bundle_topic);
      s.boolean("vehicle_bundles", c.geofence.vehicle_bundles);
      s.integer("max_bundle_bytes", c.geofence.max_bundle_bytes, 1024, 16 << 20);
      // One exact topic (the uplink subscribes to it): no filter, no empty level.
      const std::string& t = c.geofence.bundle_topic;
      if (!t.empty() && (t.front() == '/' || t.back() == '/' || t.find("//") != std::string::npos ||
                         t.find_first_of(std::string("+#\0", 3)) != std::string::npos)) {
        s.invalid("bundle_topic",
                  "must be one topic name: no '+', '#', empty levels or "
                  "leading/trailing '/'");
      }
      if (c.geofence.enabled && !c.gnss.enabled) {
        s.invalid("enabled", "geofences need a position: enable [gnss]");
      }
      if (c.geofence.enabled && c.geofence.bundle_file.empty()) {
        s.invalid("bundle_file", "must name the file that keeps the zones across restarts");
      }
    }
    {
      auto s = top.sub("status");
      s.string("socket", c.status.socket);
    }
    {
      auto s = top.sub("command");
      s.integer("clock_skew_s", c.command.clock_skew_s, 0, 3600);
      s.number("interlock_speed_kmh", c.command.interlock_speed_kmh, 0, 50);
      s.integer("interlock_motor_s", c.command.interlock_motor_s, 0, 600);
      s.integer("confirm_timeout_ms", c.command.confirm_timeout_ms, 200, 60'000);
      s.integer("retries", c.command.retries, 0, 10);
      s.choice("mc_settings_limit", c.command.mc_settings_limit, {"factory", "effective"});
      auto keys = s.sub("trusted_keys");
      keys.string_map(c.command.trusted_keys);
      auto roots = s.sub("root_keys");
      roots.string_map(c.command.root_keys);
    }
  }
  if (!problems.empty()) throw ConfigError(std::move(problems));
  return c;
}

}  // namespace

std::string Config::where(std::string_view key) const {
  const std::string file = display_name.empty() ? std::string("(defaults)") : display_name;
  const auto it = key_lines.find(key);
  if (it == key_lines.end()) return fmt::format("{}: {}", file, key);
  return fmt::format("{}:{}: {}", file, it->second, key);
}

ConfigError::ConfigError(std::vector<std::string> p)
    : std::runtime_error(join(p)), problems(std::move(p)) {}

Config parse_config(std::string_view text, const std::string& name) {
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    throw ConfigError({fmt::format("{}:{}:{}: {}", name, e.source().begin.line,
                                   e.source().begin.column, e.description())});
  }
  return parse_root(root, name);
}

Config load_config(const std::filesystem::path& file) {
  std::error_code ec;
  // An ifstream opens a directory and reads it as empty: that would be the default config.
  if (std::filesystem::is_directory(file, ec)) {
    throw ConfigError({fmt::format("{}: is a directory, not a configuration file", file.string())});
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError({fmt::format("{}: cannot open configuration file", file.string())});
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (in.bad())
    throw ConfigError({fmt::format("{}: cannot read configuration file", file.string())});
  Config c = parse_config(buffer.str(), file.string());
  c.source = file;
  return c;
}

}  // namespace fleetgw::config
