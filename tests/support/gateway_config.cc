#include "tests/support/gateway_config.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace fleetgw::testing {

std::string toml_string(const std::string& value) {
  std::string out = "\"";
  for (const char c : value) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7f) {
      char esc[8];
      std::snprintf(esc, sizeof esc, "\\u%04X", u);
      out += esc;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

GatewayConfig::GatewayConfig(const std::string& vehicle_id, const std::filesystem::path& store) {
  set_string("vehicle", "id", vehicle_id);
  set_string("log", "level", "info");
  set_string("can", "transport", "sim");
  set_string("storage", "path", store.string());
  set_string("status", "socket", "");
}

GatewayConfig::Section& GatewayConfig::section(const std::string& name) {
  const auto it = std::find_if(sections_.begin(), sections_.end(),
                               [&](const Section& s) { return s.name == name; });
  if (it != sections_.end()) return *it;
  return sections_.emplace_back(Section{name, {}});
}

GatewayConfig& GatewayConfig::set(const std::string& section_name, const std::string& key,
                                  const std::string& toml_value) {
  auto& lines = section(section_name).lines;
  const auto it =
      std::find_if(lines.begin(), lines.end(), [&](const Line& l) { return l.key == key; });
  const std::string text = key + " = " + toml_value;
  if (it != lines.end()) {
    it->text = text;
  } else {
    lines.push_back({key, text});
  }
  return *this;
}

GatewayConfig& GatewayConfig::set_string(const std::string& section_name, const std::string& key,
                                         const std::string& value) {
  return set(section_name, key, toml_string(value));
}

GatewayConfig& GatewayConfig::add_line(const std::string& section_name,
                                       const std::string& toml_line) {
  section(section_name).lines.push_back({"", toml_line});
  return *this;
}

GatewayConfig& GatewayConfig::sim(const std::filesystem::path& scenario, double speed) {
  set_string("sim", "scenario", scenario.string());
  std::ostringstream number;  // shortest form: 20, 0.5
  number << speed;
  set("sim", "speed", number.str());
  // Tests assert bus-time behaviour: on a loaded machine the ride slows down instead of the
  // bus falling behind the gateway (docs/simulator.md, "Lock-step").
  return set("sim", "lockstep", "true");
}

GatewayConfig& GatewayConfig::gnss(std::uint16_t gpsd_port) {
  set("gnss", "enabled", "true");
  set_string("gnss", "gpsd", "127.0.0.1:" + std::to_string(gpsd_port));
  return set("gnss", "reconnect_max_ms", "1000");
}

GatewayConfig& GatewayConfig::mqtt(const std::string& uri) {
  set("mqtt", "enabled", "true");
  return set_string("mqtt", "uri", uri);
}

GatewayConfig& GatewayConfig::geofence(const std::filesystem::path& bundle,
                                       const std::string& trusted_key_line) {
  set("geofence", "enabled", "true");
  set_string("geofence", "bundle_file", bundle.string());
  set("geofence", "margin_m", "5");
  return add_line("command.trusted_keys", trusted_key_line);
}

std::string GatewayConfig::text() const {
  std::string out;
  for (const auto& s : sections_) {
    out += "[" + s.name + "]\n";
    for (const auto& l : s.lines) out += l.text + "\n";
  }
  return out;
}

std::filesystem::path GatewayConfig::write(const std::filesystem::path& file) const {
  std::ofstream out(file, std::ios::trunc);
  out << text();
  out.close();
  if (!out) throw std::runtime_error("cannot write the gateway config " + file.string());
  return file;
}

GatewayConfig service_config(const std::string& vehicle_id, const std::filesystem::path& dir,
                             const std::filesystem::path& scenario, double speed,
                             const std::string& broker_uri, const std::string& key_id,
                             const std::string& public_key_b64) {
  GatewayConfig c(vehicle_id, dir / "fleetgw.db");
  c.sim(scenario, speed).set("sim", "start_now", "true");
  c.set_string("status", "socket", (dir / "status.sock").string());
  c.mqtt(broker_uri);
  c.add_line("command.trusted_keys", key_id + " = " + toml_string(public_key_b64));
  return c;
}

}  // namespace fleetgw::testing
