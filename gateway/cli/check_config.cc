#include "gateway/cli/check_config.h"

#include <fmt/format.h>
#include <unistd.h>

#include <charconv>

#include "gateway/command/key_check.h"
#include "gateway/runtime/service.h"
#include "gateway/sim/scenario.h"
#include "gateway/uplink/uplink_config_check.h"

namespace fleetgw::cli {
namespace fs = std::filesystem;
namespace {

// Why `path` cannot be read as a file, or "" when it can.
std::string unreadable_file(const fs::path& path) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (path.empty()) return "is empty";
  if (!fs::exists(st)) return fmt::format("'{}' does not exist", path.string());
  if (fs::is_directory(st)) return fmt::format("'{}' is a directory, not a file", path.string());
  if (::access(path.c_str(), R_OK) != 0) return fmt::format("cannot read '{}'", path.string());
  return "";
}

// "address:port" with a port in 1..65535 (the UDP transport's endpoint syntax).
bool valid_endpoint(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0) return false;
  int port = 0;
  const char* first = text.data() + colon + 1;
  const char* last = text.data() + text.size();
  const auto [end, ec] = std::from_chars(first, last, port);
  return ec == std::errc() && end == last && first != last && port > 0 && port <= 65535;
}

void check_storage(const config::Config& c, std::vector<std::string>& out) {
  const fs::path db(c.storage.path);
  const std::string where = c.where("storage.path");
  if (db.empty()) {
    out.push_back(where + ": must name the database file");
    return;
  }
  std::error_code ec;
  if (fs::is_directory(db, ec)) {
    out.push_back(
        fmt::format("{}: '{}' is a directory; name the database file in it", where, db.string()));
    return;
  }
  const fs::path dir = db.has_parent_path() ? db.parent_path() : fs::path(".");
  if (!fs::exists(dir, ec)) {
    out.push_back(fmt::format(
        "{}: directory '{}' does not exist (the service does not create it; create it, owned by "
        "the service user)",
        where, dir.string()));
  } else if (!fs::is_directory(dir, ec)) {
    out.push_back(fmt::format("{}: '{}' is not a directory", where, dir.string()));
  } else if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    out.push_back(fmt::format("{}: directory '{}' is not writable", where, dir.string()));
  }
}

void check_bus(const config::Config& c, std::vector<std::string>& out) {
  if (c.can.transport == "replay") {
    if (const auto why = unreadable_file(c.can.replay_file); !why.empty()) {
      out.push_back(fmt::format("{}: {}", c.where("can.replay_file"), why));
    }
  } else if (c.can.transport == "sim") {
    if (const auto why = unreadable_file(c.sim.scenario); !why.empty()) {
      out.push_back(fmt::format("{}: {}", c.where("sim.scenario"), why));
    } else {
      try {
        const sim::Scenario s = sim::load_scenario(c.sim.scenario);
        if (!c.sim.nmea_pty.empty() && s.route.empty()) {
          out.push_back(fmt::format("{}: scenario {} has no [[route]] to serve as NMEA",
                                    c.where("sim.nmea_pty"), c.sim.scenario));
        }
      } catch (const std::exception& e) {
        out.push_back(fmt::format("{}: {}", c.where("sim.scenario"), e.what()));
      }
    }
  } else if (c.can.transport == "udp") {
    for (const auto& [key, value] : {std::pair{"can.udp_local", &c.can.udp_local},
                                     std::pair{"can.udp_remote", &c.can.udp_remote}}) {
      if (!valid_endpoint(*value)) {
        out.push_back(fmt::format("{}: expected address:port (port 1..65535), got \"{}\"",
                                  c.where(key), *value));
      }
    }
  }
}

}  // namespace

std::vector<std::string> check_runnable(const config::Config& c) {
  std::vector<std::string> out;
  check_bus(c, out);
  check_storage(c, out);
  if (c.gnss.enabled && !valid_endpoint(c.gnss.gpsd)) {
    out.push_back(fmt::format("{}: expected host:port of gpsd (port 1..65535), got \"{}\"",
                              c.where("gnss.gpsd"), c.gnss.gpsd));
  }
  if (c.mqtt.enabled) {
    for (const auto& p : uplink::check_uplink_config(runtime::make_uplink_config(c))) {
      out.push_back(fmt::format("{}: {}", c.where(p.config_key), p.message));
    }
  }
  for (const auto& p : command::check_trusted_keys(c.command.trusted_keys)) {
    const std::string key = "command.trusted_keys" + (p.key_id.empty() ? "" : "." + p.key_id);
    out.push_back(fmt::format("{}: {}", c.where(key), p.message));
  }
  for (const auto& p : command::check_root_keys(c.command.root_keys)) {
    out.push_back(fmt::format("{}: {}", c.where("command.root_keys." + p.key_id), p.message));
  }
  return out;
}

config::Config load_runnable_config(const fs::path& file,
                                    const std::function<void(config::Config&)>& adjust) {
  config::Config c = config::load_config(file);
  if (adjust) adjust(c);
  if (auto problems = check_runnable(c); !problems.empty()) {
    throw config::ConfigError(std::move(problems));
  }
  return c;
}

void print_config_error(const config::ConfigError& e, std::ostream& err) {
  for (const auto& p : e.problems) err << p << '\n';
  err << e.problems.size() << " problem(s) in the configuration\n";
}

int run_check_config(const fs::path& file, std::ostream& out, std::ostream& err) {
  try {
    (void)load_runnable_config(file);
  } catch (const config::ConfigError& e) {
    print_config_error(e, err);
    return 1;
  }
  out << file.string() << ": OK\n";
  return 0;
}

}  // namespace fleetgw::cli
