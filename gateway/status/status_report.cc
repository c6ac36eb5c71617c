#include "gateway/status/status_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace fleetgw::status {
namespace {

using nlohmann::json;

// Defensive accessors: the document comes over a socket from another process (possibly another
// version), so a missing or mistyped field is a finding, never an exception.
const json* member(const json& j, const char* key) {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(key);
  return it == j.end() ? nullptr : &*it;
}

std::string str(const json& j, const char* key, std::string fallback = "?") {
  const json* v = member(j, key);
  return v && v->is_string() ? v->get<std::string>() : fallback;
}

std::optional<double> num(const json& j, const char* key) {
  const json* v = member(j, key);
  if (v && v->is_number()) return v->get<double>();
  return std::nullopt;
}

std::optional<bool> boolean(const json& j, const char* key) {
  const json* v = member(j, key);
  if (v && v->is_boolean()) return v->get<bool>();
  return std::nullopt;
}

uint64_t count(const json& j, const char* key) {
  const auto v = num(j, key);
  return v && *v > 0 ? static_cast<uint64_t>(*v) : 0;
}

std::string age_text(double seconds) {
  if (seconds < 0) seconds = 0;
  if (seconds < 60) return fmt::format("{:.1f} s", seconds);
  if (seconds < 3600) return fmt::format("{:.1f} min", seconds / 60);
  if (seconds < 48 * 3600) return fmt::format("{:.1f} h", seconds / 3600);
  return fmt::format("{:.1f} d", seconds / 86400);
}

std::string bytes_text(double b) {
  if (b < 1024) return fmt::format("{:.0f} B", b);
  if (b < 1024.0 * 1024) return fmt::format("{:.1f} KiB", b / 1024);
  if (b < 1024.0 * 1024 * 1024) return fmt::format("{:.1f} MiB", b / (1024.0 * 1024));
  return fmt::format("{:.2f} GiB", b / (1024.0 * 1024 * 1024));
}

// "21.3 km/h  SOC 63 %  riding: 2.10 km in 6.0 min (ride R)" / "... parked"; unknown values
// are "?" (the service has not heard them yet).
std::string vehicle_text(const json& v) {
  const auto speed = num(v, "speed_kmh");
  const auto soc = num(v, "soc_pct");
  std::string text = fmt::format("{} km/h  SOC {} %", speed ? fmt::format("{:.1f}", *speed) : "?",
                                 soc ? fmt::format("{:.0f}", *soc) : "?");
  const json* ride = member(v, "ride");
  if (ride && ride->is_object()) {
    text += fmt::format("  riding: {:.2f} km in {:.1f} min (ride {})",
                        num(*ride, "distance_km").value_or(0),
                        num(*ride, "duration_s").value_or(0) / 60, str(*ride, "ride_id"));
  } else {
    text += "  parked";
  }
  return text;
}

}  // namespace

Health health_from_json(const json& status) {
  Health h;
  const auto object = [&](const char* key) -> const json* {
    const json* s = member(status, key);
    return s && s->is_object() ? s : nullptr;
  };
  const auto array = [&](const char* key) -> const json* {
    const json* s = member(status, key);
    return s && s->is_array() ? s : nullptr;
  };
  if (const json* bus = object("bus")) {
    h.bus = BusFacts{str(*bus, "interface"), str(*bus, "state"), str(*bus, "detail", "")};
  }
  if (const json* nodes = array("nodes")) {
    h.nodes.emplace();
    for (const auto& n : *nodes) {
      h.nodes->push_back(
          {str(n, "name"), boolean(n, "online").value_or(false), num(n, "last_heard_age_s")});
    }
  }
  if (const json* faults = array("faults")) {
    h.faults.emplace();
    for (const auto& f : *faults) {
      h.faults->push_back({str(f, "node"), static_cast<std::int64_t>(count(f, "code")),
                           str(f, "name"), str(f, "severity")});
    }
  }
  h.has_locks = array("locks") != nullptr;
  if (const json* broker = object("broker")) {
    h.broker = BrokerFacts{boolean(*broker, "enabled").value_or(true),
                           boolean(*broker, "connected").value_or(false),
                           str(*broker, "uri"),
                           str(*broker, "last_error", ""),
                           str(*broker, "last_publish_refusal", ""),
                           count(*broker, "refused_records")};
  }
  if (const json* g = object("gnss")) {
    h.gnss = GnssFacts{boolean(*g, "enabled").value_or(false),
                       boolean(*g, "connected").value_or(true), str(*g, "gpsd")};
  }
  if (const json* st = object("storage")) {
    StorageFacts f;
    f.failing = boolean(*st, "failing").value_or(false);
    f.last_error = str(*st, "last_error", "unknown error");
    f.failed_writes = count(*st, "failed_writes");
    f.failing_for_s = num(*st, "failing_for_s");
    f.configured_budget_bytes = count(*st, "configured_budget_bytes");
    f.effective_budget_bytes = count(*st, "effective_budget_bytes");
    f.dropped_records = count(*st, "dropped_records");
    h.storage = std::move(f);
  }
  if (const json* disk = object("disk")) {
    h.disk = DiskFacts{count(*disk, "used_bytes"), count(*disk, "budget_bytes")};
  }
  if (const json* outbox = object("outbox")) {
    h.outbox = OutboxFacts{count(*outbox, "depth"), num(*outbox, "oldest_unsent_age_s")};
  }
  return h;
}

std::vector<Attention> evaluate(const Health& h, const AttentionRules& rules) {
  std::vector<Attention> out;
  auto missing = [&](const char* key, bool array) {
    out.push_back(
        {"malformed", fmt::format("status has no \"{}\" {}", key, array ? "list" : "section")});
  };
  if (!h.bus) {
    missing("bus", false);
  } else if (h.bus->state != "up") {
    out.push_back({"bus", fmt::format("CAN bus {} is {}{}{}", h.bus->interface, h.bus->state,
                                      h.bus->detail.empty() ? "" : ": ", h.bus->detail)});
  }
  if (!h.nodes) {
    missing("nodes", true);
  } else {
    for (const auto& n : *h.nodes) {
      if (n.online) continue;
      out.push_back(
          {"node",
           fmt::format("node {} offline ({})", n.name,
                       n.last_heard_age_s ? "last heard " + age_text(*n.last_heard_age_s) + " ago"
                                          : std::string("never heard"))});
    }
  }
  if (!h.faults) {
    missing("faults", true);
  } else {
    for (const auto& f : *h.faults) {
      if (f.severity != "critical") continue;
      out.push_back({"fault", fmt::format("critical fault on {}: {} (code {})", f.node, f.name,
                                          std::max<std::int64_t>(0, f.code.value_or(0)))});
    }
  }
  if (!h.has_locks) missing("locks", true);  // informational, but a provider dropping it is broken
  if (!h.broker) {
    missing("broker", false);
  } else {
    const BrokerFacts& b = *h.broker;
    if (b.enabled && !b.connected) {
      out.push_back({"broker", fmt::format("broker {} not connected{}{}", b.uri,
                                           b.last_error.empty() ? "" : ": ", b.last_error)});
    }
    // MQTT 5: the broker answers publishes with a refusal (e.g. an ACL's 0x87).
    if (!b.last_publish_refusal.empty()) {
      out.push_back({"broker", fmt::format("broker refuses publishes: {}; {} record(s) kept in "
                                           "the outbox, retried with back-off",
                                           b.last_publish_refusal, b.refused_records)});
    }
  }
  // Optional section (older services do not send it).
  if (h.gnss && h.gnss->enabled && !h.gnss->connected) {
    out.push_back({"gnss", fmt::format("gpsd at {} unreachable: position unknown", h.gnss->gpsd)});
  }
  if (const auto& st = h.storage) {
    if (st->failing) {
      out.push_back(
          {"storage",
           fmt::format("store writes failing{}: {} ({} failed writes)",
                       st->failing_for_s ? " for " + age_text(*st->failing_for_s) : std::string(),
                       st->last_error, st->failed_writes)});
    }
    const auto configured = static_cast<double>(st->configured_budget_bytes);
    const auto effective = static_cast<double>(st->effective_budget_bytes);
    if (effective > 0 && configured > effective) {
      out.push_back({"budget", fmt::format("disk budget clamped to {} (storage.max_mb asks for {}, "
                                           "more than the disk holds)",
                                           bytes_text(effective), bytes_text(configured))});
    }
  }
  if (!h.disk) {
    missing("disk", false);
  } else {
    const auto used = static_cast<double>(h.disk->used_bytes);
    const auto budget = static_cast<double>(h.disk->budget_bytes);
    if (budget > 0 && used > rules.disk_fraction * budget) {
      out.push_back(
          {"disk", fmt::format("store uses {} of its {} budget ({:.0f} %)", bytes_text(used),
                               bytes_text(budget), 100.0 * used / budget)});
    }
  }
  if (!h.outbox) {
    missing("outbox", false);
  } else {
    const auto& age = h.outbox->oldest_unsent_age_s;
    const auto limit = static_cast<double>(rules.outbox_max_age.count());
    if (age && *age > limit) {
      out.push_back({"outbox", fmt::format("oldest unsent record is {} old ({} records waiting)",
                                           age_text(*age), h.outbox->depth)});
    }
  }
  return out;
}

std::vector<Attention> evaluate(const json& status, const AttentionRules& rules) {
  return evaluate(health_from_json(status), rules);
}

std::string format_summary(const json& s, const std::vector<Attention>& findings) {
  std::string out;
  auto line = [&](std::string_view label, const std::string& text) {
    out += fmt::format("{:<8} {}\n", label, text);
  };
  const json empty = json::object();
  auto sec = [&](const char* key) -> const json& {
    const json* v = member(s, key);
    return v ? *v : empty;
  };

  std::string head = fmt::format("fleetgw {}  vehicle {}", str(s, "version"), str(s, "vehicle_id"));
  if (const auto up = num(s, "uptime_s")) head += "  up " + age_text(*up);
  out += head + '\n';

  const json& bus = sec("bus");
  std::string bus_text =
      fmt::format("{} ({}): {}  rx {}  tx {}  tx failures {}  error frames {}  reopens {}",
                  str(bus, "interface"), str(bus, "transport"), str(bus, "state"),
                  count(bus, "rx_frames"), count(bus, "tx_frames"), count(bus, "tx_failures"),
                  count(bus, "error_frames"), count(bus, "reopens"));
  if (const json* fe = member(bus, "frame_errors"); fe && fe->is_object()) {
    std::string errs;
    for (const auto& [k, v] : fe->items()) {
      if (v.is_number() && v.get<double>() > 0) errs += fmt::format(" {} {}", k, v.dump());
    }
    bus_text += "\n         frame errors:" + (errs.empty() ? std::string(" none") : errs);
  }
  line("bus", bus_text);

  std::string nodes_text;
  if (const json* nodes = member(s, "nodes"); nodes && nodes->is_array()) {
    for (const auto& n : *nodes) {
      const auto age = num(n, "last_heard_age_s");
      if (!nodes_text.empty()) nodes_text += "\n         ";
      nodes_text += fmt::format("{:<6} {:<8} {:<22} firmware {}", str(n, "name"),
                                boolean(n, "online").value_or(false) ? "online" : "OFFLINE",
                                age ? "heard " + age_text(*age) + " ago" : "never heard",
                                str(n, "firmware", "unknown"));
    }
  }
  line("nodes", nodes_text.empty() ? "none" : nodes_text);

  std::string faults_text;
  if (const json* faults = member(s, "faults"); faults && faults->is_array()) {
    for (const auto& f : *faults) {
      if (!faults_text.empty()) faults_text += "\n         ";
      faults_text += fmt::format("{} {} (code {}, {})", str(f, "node"), str(f, "name"),
                                 count(f, "code"), str(f, "severity"));
    }
  }
  line("faults", faults_text.empty() ? "none" : faults_text);

  std::string locks_text;
  if (const json* locks = member(s, "locks"); locks && locks->is_array()) {
    for (const auto& l : *locks) {
      if (!locks_text.empty()) locks_text += "  ";
      locks_text += fmt::format("{}: {}", str(l, "kind"), str(l, "state"));
    }
  }
  line("locks", locks_text.empty() ? "none" : locks_text);
  if (const json* v = member(s, "vehicle"); v && v->is_object()) line("vehicle", vehicle_text(*v));

  const json& broker = sec("broker");
  if (!boolean(broker, "enabled").value_or(true)) {
    line("broker", "disabled (mqtt.enabled = false)");
  } else {
    const bool connected = boolean(broker, "connected").value_or(false);
    const std::string err = str(broker, "last_error", "");
    std::string text =
        fmt::format("{}: {}{}", str(broker, "uri"), connected ? "connected" : "DISCONNECTED",
                    !connected && !err.empty() ? " (" + err + ")" : "");
    if (const auto tls = count(broker, "tls_failures"); tls > 0) {
      text += fmt::format("\n         TLS failures {}", tls);
    }
    const std::string last = str(broker, "last_connect_error", "");
    if (connected && !last.empty()) {
      const auto age = num(broker, "last_connect_error_age_s");
      text += fmt::format("\n         last connect error{}: {}",
                          age ? " " + age_text(*age) + " ago" : std::string(), last);
    }
    if (const std::string p = str(broker, "protocol", ""); !p.empty()) {
      text += fmt::format("\n         MQTT {}", p);
      if (const auto n = count(broker, "publish_refusals"); n > 0) {
        text += fmt::format(", {} publish(es) refused by the broker", n);
      }
    }
    if (const std::string refusal = str(broker, "last_publish_refusal", ""); !refusal.empty()) {
      text += fmt::format("\n         publishes REFUSED: {}", refusal);
    }
    line("broker", text);
  }

  if (const json* c = member(s, "commands"); c && c->is_object()) {
    std::string text =
        fmt::format("{} received ({} unauthenticated), {} answered busy", count(*c, "received"),
                    count(*c, "unauthenticated"), count(*c, "busy"));
    const json* by = member(*c, "dropped_by_reason");
    text += fmt::format("\n         {} dropped", count(*c, "dropped"));
    if (by && by->is_object() && count(*c, "dropped") > 0) {
      std::string classes;
      for (const auto& [k, v] : by->items()) {
        if (v.is_number() && v.get<double>() > 0) {
          classes += fmt::format("{}{} {}", classes.empty() ? "" : ", ", k, v.dump());
        }
      }
      if (!classes.empty()) text += " (" + classes + ")";
    }
    line("commands", text);
  }

  const json& outbox = sec("outbox");
  const auto oldest = num(outbox, "oldest_unsent_age_s");
  line("outbox", fmt::format("{} records{}", count(outbox, "depth"),
                             oldest ? ", oldest unsent " + age_text(*oldest) + " ago" : ""));

  const json& disk = sec("disk");
  const double used = num(disk, "used_bytes").value_or(0);
  const double budget = num(disk, "budget_bytes").value_or(0);
  line("disk", budget > 0 ? fmt::format("{} of {} ({:.1f} %)", bytes_text(used), bytes_text(budget),
                                        100.0 * used / budget)
                          : bytes_text(used));

  if (const json* st = member(s, "storage"); st && st->is_object()) {
    std::string text;
    if (boolean(*st, "failing").value_or(false)) {
      const auto since = num(*st, "failing_for_s");
      text = fmt::format("WRITES FAILING{}: {}", since ? " for " + age_text(*since) : std::string(),
                         str(*st, "last_error", "unknown error"));
    } else {
      text = "writing";
    }
    text += fmt::format("  failed writes {}  dropped records {}", count(*st, "failed_writes"),
                        count(*st, "dropped_records"));
    const double configured = num(*st, "configured_budget_bytes").value_or(0);
    const double effective = num(*st, "effective_budget_bytes").value_or(0);
    if (effective > 0 && configured > effective) {
      text += fmt::format("\n         budget clamped to {} (storage.max_mb: {})",
                          bytes_text(effective), bytes_text(configured));
    }
    line("storage", text);
  }

  if (const json* g = member(s, "gnss"); g && g->is_object()) {
    std::string text;
    if (boolean(*g, "fix").value_or(false)) {
      text =
          fmt::format("fix {:.6f}, {:.6f}", num(*g, "lat").value_or(0), num(*g, "lon").value_or(0));
      if (const auto hdop = num(*g, "hdop")) text += fmt::format("  hdop {:.1f}", *hdop);
      text += fmt::format("  {} satellites", count(*g, "satellites"));
    } else {
      text = fmt::format("POSITION UNKNOWN: {}", str(*g, "reason", "no fix"));
      if (const auto age = num(*g, "last_fix_age_s"))
        text += ", last fix " + age_text(*age) + " ago";
    }
    text += fmt::format("  (gpsd {})", str(*g, "gpsd"));
    line("gnss", text);
  }

  if (const json* g = member(s, "geofence"); g && g->is_object()) {
    std::string text;
    if (num(*g, "version")) {
      text =
          fmt::format("version {} in force: {} zones, {} vertices, key '{}'", count(*g, "version"),
                      count(*g, "zones"), count(*g, "vertices"), str(*g, "key_id"));
    } else {
      text = "NO ZONES in force (no bundle accepted yet)";
    }
    text += fmt::format("\n         bundles: {} received, {} accepted, {} refused",
                        count(*g, "bundles_received"), count(*g, "bundles_accepted"),
                        count(*g, "bundles_refused"));
    if (const auto dropped = count(*g, "bundles_dropped"); dropped > 0) {
      // The newcomer is dropped: a retained bundle comes again at the next connect.
      text += fmt::format(", {} dropped (queue full)", dropped);
    }
    if (const std::string r = str(*g, "last_refusal", ""); !r.empty()) {
      const auto age = num(*g, "last_refusal_age_s");
      const std::string topic = str(*g, "last_refusal_topic", "");
      text += fmt::format("\n         last refused{}{}: {}", topic.empty() ? "" : " on " + topic,
                          age ? " " + age_text(*age) + " ago" : std::string(), r);
    }
    if (boolean(*g, "outside_operating_area").value_or(false)) {
      text += "\n         OUTSIDE EVERY OPERATING AREA";
    }
    line("geofence", text);
  }

  if (const json* r = member(s, "revocations"); r && r->is_object()) {
    line("roots", num(*r, "version")
                      ? fmt::format("revocation list version {} in force", count(*r, "version"))
                      : std::string("no revocation list in force (none received yet)"));
  }

  out += '\n';
  if (findings.empty()) {
    out += "OK\n";
  } else {
    for (const auto& f : findings) out += fmt::format("ATTENTION: {}\n", f.detail);
  }
  return out;
}

}  // namespace fleetgw::status
